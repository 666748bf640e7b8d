"""HierarchicalMethod: the paper's method (Sec. III, Algorithm 2) behind the Method contract.

Per step and for every group z of B episodes at once (no loop over groups or robots):
receive S_t^z over the lossy channel, update the GRU predictors and complete S-hat^z
(eq:predictor_input..eq:interaction_state_collection), sample (training) or take the
argmax (execution) of the reference r ~ mu_psi_z and the joint control U~ ~ pi_theta_z,
then run the safety filter (Algorithm 1) to get the executed U_t^z.

Training (``update``, see ``training.py``): the centralized critic V_omega on the global
state gives the team advantage, used for both policy levels (eq:losses), Adam; the GRU
predictors are trained with their own supervised loss and optimizer (eq:gru_pred_loss).

Variants (parameters, defaults are the paper's; docs/decisions/0118): what fills
lost links (``messages``), the fallback (``fallback``), resampling a fallen-back group at
argmax execution (``resample_on_fallback``) and the reference layer's open choices
(``ref_hold``, ``ref_lr``, ``ref_entropy_coef``, ``ref_embed_scale``).

Each step reports the inter-group links delivered (``Decision.group_links``) and the
filter's outcome to a ``Method.run`` observer (algorithms/common/observer.py). Probes that
need the intermediates (mu's log-probs, the completed S-hat) subclass the method and
override ``policy_forward`` or ``_receive`` (scripts/reference_probe.py, the tests).
May import: algorithms.base, algorithms.common, algorithms.hierarchical (not reports, bench).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from algorithms.base import REFERENCE, Method
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice, sample_categorical
from algorithms.common.ppo import MAPPO, RobotCritic
from algorithms.common.seed_stack import new_view
from algorithms.common.trainer import CRITIC_FEATURES, CentralCritic, RolloutBuffer, critic_features
from algorithms.hierarchical.fallback import offenders_wait
from algorithms.hierarchical.mappo import mappo_policy_update
from algorithms.hierarchical.messages import (
    CTRL,
    MSG_DIM,
    POS,
    PRESENT,
    group_messages,
    group_structure,
)
from algorithms.hierarchical.params import PRESETS, HierarchicalParams
from algorithms.hierarchical.policies import (
    LocalPolicy,
    ReferencePolicy,
    neighbor_patch_size,
    neighbor_patches,
    policy_forward,
)
from algorithms.hierarchical.predictor import (
    GroupPredictor,
    PredictorState,
    SnapToFree,
    initial_state,
    rollout_step,
)
from algorithms.hierarchical.safety_filter import SafetyFilter
from algorithms.hierarchical.training import Learner, policy_update, predictor_update
from envs.actions import N_ACTIONS, WAIT
from envs.channel import Channel
from envs.config import EnvConfig
from envs.observations import PatchExtractor, feature_size, robot_features


@dataclass
class Received:
    """What group z holds of the other groups at one step (B episodes, K links, n slots)."""

    avail: np.ndarray  # (B, Z, K) link delivered this step
    own_msgs: np.ndarray  # (B, Z, n, D) true messages S_t^z of each group
    link_msgs: np.ndarray  # (B, Z, K, n, D) true messages on each link
    m_hat: np.ndarray  # (B, Z, K, n, D) completed S-hat (eq:interaction_state_estimate)
    present: np.ndarray  # (B, Z, K, n) sender's robot on the floor, as received or predicted
    cells: np.ndarray  # (B, Z, K, n) its cell, snapped to a free cell
    heading: np.ndarray  # (B, Z, K, n) the cell its last control leads to
    lost: np.ndarray  # (B, Z, K) valid link lost this step
    sq_err: np.ndarray  # (B,) summed squared position error of the predictions on lost links
    n_lost: np.ndarray  # (B,) lost links predicted


@dataclass
class Controller:
    """Per-batch controller state (one per ``run``)."""

    channel: Channel
    patch: PatchExtractor
    pred: PredictorState | None = None
    buffer: RolloutBuffer | None = None
    running: np.ndarray | None = None  # (B,) episodes running before the current step
    t: int = 0  # steps decided so far
    ref: torch.Tensor | None = None  # (Z, B) reference in force (held for ``ref_hold`` steps)
    resample_gen: torch.Generator | None = None  # resample_on_fallback at argmax execution


class HierarchicalMethod(Method):
    name = "hierarchical"
    display_name = "Hierarchical (ours)"
    color = "#0173b2"
    legend_rank = 0
    paper_role = REFERENCE  # the paper's own method
    safety_filter_default = True  # Sec. III-C: the predictive safety filter is part of the method
    payload_model = ("scalars transmitted per step on the inter-group links, delivered or lost: (Z - 1) N d_m "
                     "on the complete group graph, fewer on a sparser one (Sec. III-A)")
    Params = HierarchicalParams
    presets = PRESETS  # "tuned": decision 0215
    params: HierarchicalParams

    def __init__(self, env: EnvConfig, params: dict[str, Any] | None = None, seed: int = 0,
                 device: Any = None) -> None:
        super().__init__(env, params, seed, device)
        p = self.params
        self.gs = group_structure(env)
        z = env.groups
        pz = 1 if p.share_params else z
        self.d_own = feature_size(p.obs_radius)
        self.d_nbr = neighbor_patch_size(p.obs_radius)
        self.reference = ReferencePolicy(pz, z, self.d_own + self.d_nbr, p.hidden, p.ref_size)
        self.local = LocalPolicy(pz, z, self.d_own, p.hidden, p.ref_size, p.obs_radius)
        if p.ref_embed_scale != 0.5:  # LocalPolicy initializes it with std 0.5
            with torch.no_grad():
                self.local.ref_embed.mul_(p.ref_embed_scale / 0.5)
        self.predictor = GroupPredictor(pz, z, self.layout.shape, p.predictor_hidden, p.predictor_embed)
        self.mappo = p.protocol == MAPPO  # algorithms/hierarchical/mappo.py
        self.critic: CentralCritic | RobotCritic = RobotCritic(p.critic_hidden) if self.mappo \
            else CentralCritic(p.critic_hidden)
        lr = p.ppo_lr if self.mappo else p.lr
        if p.ref_lr is None:  # one group: checkpoints keep the optimizer layout of the default
            self.opt_policy = torch.optim.Adam(
                [*self.reference.parameters(), *self.local.parameters()], lr=lr)
        else:
            param_groups: list[dict[str, Any]] = [
                {"params": list(self.reference.parameters()), "lr": p.ref_lr},
                {"params": list(self.local.parameters())}]
            self.opt_policy = torch.optim.Adam(param_groups, lr=lr)
        self.opt_critic = torch.optim.Adam(self.critic.parameters(), lr=p.critic_lr)
        self.opt_predictor = torch.optim.Adam(self.predictor.parameters(), lr=p.predictor_lr)
        self.filter = SafetyFilter(self.layout, p.search_radius, p.c_max)
        self.snap = SnapToFree(self.layout)
        self._decoders: list[tuple[GroupPredictor, int, int]] | None = None  # a stack view's seeds
        self.place_modules()

    # ------------------------------------------------------------ seed stacking
    STACKED = ("reference", "local", "predictor")  # the modules a rollout runs
    STACK_AXIS = 1  # the episodes' axis of its logits (Z, B, ..., K)

    @classmethod
    def stackable(cls, params: Mapping[str, Any]) -> bool:
        # Per-group and shared parameters alike (``stack_view``; docs/decisions/0202, 0237).
        return True

    @classmethod
    def stack_view(cls, methods: Sequence[Method]) -> HierarchicalMethod:
        """The rollout of S seeds of one configuration as one batch (seed_stack): a method
        whose per-group weights are the seeds' stacked group-major (Z S groups, see
        ``group_layers``; shared parameters: S sets, ``per_slice``); each seed's predictor
        decodes its own lost links."""
        view: HierarchicalMethod = new_view(cls, methods)
        for name in cls.STACKED:
            for mod in getattr(view, name).modules():
                if hasattr(mod, "seeds"):
                    mod.seeds = len(methods)
        return view

    def load_stack(self, methods: Sequence[Method]) -> None:
        b = self.params.batch_episodes
        with torch.no_grad():
            for name in self.STACKED:
                per_seed = [dict(getattr(m, name).named_parameters()) for m in methods]
                for key, param in getattr(self, name).named_parameters():
                    stacked = torch.stack([ps[key] for ps in per_seed], dim=1)  # (Z, S, ...)
                    param.data = stacked.reshape(-1, *stacked.shape[2:])
        self._decoders = [(m.predictor, k * b, (k + 1) * b) for k, m in enumerate(methods)]  # type: ignore[attr-defined]  # stack_view's

    def modules(self) -> dict[str, torch.nn.Module | torch.optim.Optimizer]:
        return {
            "reference": self.reference, "local": self.local, "predictor": self.predictor,
            "critic": self.critic, "opt_policy": self.opt_policy, "opt_critic": self.opt_critic,
            "opt_predictor": self.opt_predictor,
        }

    # ------------------------------------------------------------- controller
    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> Controller:
        p = self.params
        core = batch.core
        ctrl = Controller(batch.open_channel("groups"), PatchExtractor(core, p.obs_radius))
        if choice.mode.greedy and p.resample_on_fallback:  # derived from the batch seed, no draw from its rng
            seq = batch.rng.bit_generator.seed_seq
            assert isinstance(seq, np.random.SeedSequence)  # EpisodeBatch seeds every rng from one
            child = np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, 0x5E5A))
            ctrl.resample_gen = torch.Generator().manual_seed(int(child.generate_state(1, np.uint64)[0] >> 2))
        if choice.training:
            b, n, zz = core.batch, core.n, self.env.groups
            slots, links = self.gs.n_slots, self.gs.neighbors.shape[1]
            ctrl.buffer = RolloutBuffer(self.env.horizon, b, {
                "own": ((n, self.d_own), np.float16),
                "nbr": ((n, self.d_nbr), np.uint8),
                "controlled": ((n,), np.bool_),
                "action_mask": ((n, N_ACTIONS), np.bool_),
                "ref": ((zz,), np.int64),
                "ref_new": ((zz,), np.bool_),
                "group_reward": ((zz,), np.float32),
                "proposed": ((n,), np.int64),
                "critic": ((n, CRITIC_FEATURES), np.float32),
                "msgs": ((zz, slots, MSG_DIM), np.float32),
                "avail": ((zz, links), np.bool_),
                "age": ((zz, links), np.int64),
                **({"robot_reward": ((n,), np.float32)} if self.mappo else {}),
            })
        return ctrl

    def decide(self, batch: EpisodeBatch, state: Controller, choice: ActionChoice) -> Decision:
        p = self.params
        core, gs = batch.core, self.gs
        state.running = ~core.ended
        # Channel and predictor: S_t^z, A_t^{z',z} -> S-hat_t^z.
        group_links = state.channel.step()  # (B, Z', Z)
        rx = self._receive(core, state, gs.link_availability(group_links))

        # Policies: r ~ mu(. | Enc_r(X, G, S-hat)), U~ ~ pi(. | Enc_u(X, G, r)).
        # float16 rounding by torch: the same IEEE round-to-nearest-even values as numpy's
        # astype (tests/algorithms/hierarchical/test_hot_paths.py), 15x faster at rollout sizes.
        own = torch.from_numpy(robot_features(core, state.patch, gs.groups)).to(torch.float16).numpy()
        nbr = neighbor_patches(state.patch, gs, rx.cells, rx.present, rx.heading)
        controlled = ~core.done & state.running[:, None]
        action_mask = self.layout.move_valid[core.pos]
        ref_in, ref_new = self._reference_input(
            state, core.batch, choice.gen if choice.gen is not None else self.torch_gen)
        with torch.no_grad():
            ref, ref_logp, logp = self.policy_forward(own, nbr, controlled, action_mask, ref=ref_in,
                                                      choice=choice)
            logp = logp.cpu()  # sampling and the filter read it on the host (one copy from a device)
            proposed_g = choice(logp)  # (Z, B, n), the same mode as r
        state.ref, state.t = ref, state.t + 1
        proposed = np.where(controlled, gs.scatter(proposed_g.numpy().swapaxes(0, 1), core.n), WAIT)

        dec = Decision(actions=proposed, proposed=proposed, payload=float(state.channel.payload_hier),
                       pred_sq_err=rx.sq_err, pred_count=rx.n_lost, group_links=group_links)
        if p.safety_filter:
            self._apply_filter(core, rx.cells, rx.present, controlled, proposed, logp, dec,
                               resample=choice.mode.greedy and p.resample_on_fallback, gen=state.resample_gen)
        if state.buffer is not None:
            assert state.pred is not None
            state.buffer.add(own=own, nbr=nbr, controlled=controlled, action_mask=action_mask,
                             ref=ref.cpu().numpy().T, ref_new=np.broadcast_to(ref_new, ref.shape).T,
                             proposed=proposed, critic=critic_features(core),
                             msgs=rx.own_msgs, avail=rx.avail, age=state.pred.age)
        return dec

    def _receive(self, core: Any, state: Controller, avail: np.ndarray) -> Received:
        """S_t^z over the links ``avail`` (B, Z, K) -> S-hat_t^z: the GRU predictors are
        stepped (state.pred) and lost links completed (eq:predictor_input..
        eq:interaction_state_collection)."""
        gs = self.gs
        own_msgs = group_messages(core, gs)  # (B, Z, n, D)
        link_msgs = gs.links(own_msgs)  # (B, Z, K, n, D)
        if state.pred is None:
            state.pred = initial_state(self.predictor, link_msgs)
        m_hat = self._complete_messages(state.pred, link_msgs, avail, own_msgs)
        sender_slots = gs.slot_valid[np.maximum(gs.neighbors, 0)] & gs.link_valid[..., None]  # (Z, K, n)
        present = (m_hat[..., PRESENT] > 0.5) & sender_slots[None]
        cells = self.snap(m_hat[..., POS])  # (B, Z, K, n)
        heading = self.layout.next_cell[cells, m_hat[..., CTRL].argmax(-1)]
        lost = ~avail & gs.link_valid[None]
        sq_err, n_lost = self._prediction_error(cells, link_msgs, lost, sender_slots)
        return Received(avail, own_msgs, link_msgs, m_hat, present, cells, heading, lost, sq_err, n_lost)

    def _complete_messages(self, pred: PredictorState, link_msgs: np.ndarray, avail: np.ndarray,
                           own_msgs: np.ndarray) -> np.ndarray:
        """M-hat (B, Z, K, n, D) (eq:interaction_state_estimate): received messages on delivered
        links; on lost links the GRU prediction (paper), the ground truth (``messages="oracle"``,
        an upper bound for any predictor) or the last received message (``"last"``)."""
        mode = self.params.messages
        if mode == "predicted":
            with torch.no_grad():
                return rollout_step(self.predictor, pred, link_msgs, avail, own_msgs, self._decoders)
        pred.age = np.where(avail, 0, pred.age + 1)  # the memory rollout_step keeps, no GRU
        pred.mem = np.where(avail[..., None, None], link_msgs, pred.mem)
        return link_msgs.copy() if mode == "oracle" else pred.mem.copy()

    def _reference_input(self, state: Controller, batch: int, gen: torch.Generator,
                         ) -> tuple[torch.Tensor | None, np.ndarray]:
        """The r to impose this step, or None to draw r from mu; and whether r is new (Z, 1).

        A drawn r is held for ``ref_hold`` steps (paper: 1). A probe subclass may impose r
        (a fixed or uniform r is not mu's decision: return False for it)."""
        z = self.env.groups
        hold = self.params.ref_hold
        if state.ref is not None and state.t % hold != 0:
            return state.ref, np.zeros((z, 1), bool)
        return None, np.ones((z, 1), bool)

    def observe(self, batch: EpisodeBatch, state: Controller, result: Any) -> None:
        if state.buffer is not None:
            assert state.running is not None  # set by decide() before every step
            # Group z's part of eq:reward: its robots' terms over N (sums to the team reward).
            terms = result.progress + result.goal_bonus + result.collision_penalty + result.time_penalty
            state.buffer.data["group_reward"][state.buffer.t] = (
                self.gs.gather(terms, fill=0.0).sum(-1) / self.env.n_robots)
            if self.mappo:
                state.buffer.data["robot_reward"][state.buffer.t] = terms
            state.buffer.reward(result.reward, state.running)

    # ---------------------------------------------------------------- helpers
    def policy_forward(self, own: np.ndarray, nbr: np.ndarray, controlled: np.ndarray,
                       action_mask: np.ndarray, ref: torch.Tensor | None,
                       choice: ActionChoice | None = None,
                       ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Both levels for M rows: own (M, N, F) float16, nbr (M, N, P) uint8, controlled
        (M, N), action_mask (M, N, 5). Samples r when ``ref`` is None. Returns r (Z, M),
        log mu (Z, M, |R|) and the local per-robot log-probs (Z, M, n, 5)
        (``policies.policy_forward``; r from the training stream unless ``choice`` says)."""
        if ref is None and choice is None:
            choice = ActionChoice.train(self.torch_gen)
        return policy_forward(self.reference, self.local, self.gs, own, nbr, controlled, action_mask,
                              ref, choice)

    def _apply_filter(self, core: Any, cells: np.ndarray, present: np.ndarray, controlled: np.ndarray,
                      proposed: np.ndarray, logp: torch.Tensor, dec: Decision, resample: bool = False,
                      gen: torch.Generator | None = None) -> None:
        """Algorithm 1 for every (episode, group); the variants ``fallback="per_robot"`` and
        ``resample_on_fallback`` (argmax execution only) act on the groups that fell back."""
        gs, b, z = self.gs, core.batch, self.env.groups
        g = b * z
        blocked = self.filter.blocked_cells(cells.reshape(g, -1), present.reshape(g, -1))
        pos = gs.gather(core.pos).reshape(g, -1)
        occ = gs.gather(core.occupying, fill=False).reshape(g, -1)
        ctl = gs.gather(controlled, fill=False).reshape(g, -1)
        lp = logp.cpu().numpy().swapaxes(0, 1).reshape(g, -1, N_ACTIONS).astype(np.float64)
        prop = gs.gather(proposed, fill=WAIT).reshape(g, -1)
        res = self.filter(pos, occ, ctl, prop, lp, blocked)
        if resample and res.fallback.any():  # one fresh sample from pi, filtered again
            fb = np.flatnonzero(res.fallback)
            logits = torch.from_numpy(lp[fb])
            redo = sample_categorical(logits, 1.0, gen if gen is not None else self.torch_gen).numpy()  # (F, n)
            prop[fb] = np.where(ctl[fb], redo, WAIT)
            again = self.filter(pos[fb], occ[fb], ctl[fb], prop[fb], lp[fb], blocked[fb])
            res.actions[fb], res.fallback[fb] = again.actions, again.fallback
            res.examined[fb] += again.examined
        if self.params.fallback == "per_robot" and res.fallback.any():
            fb = np.flatnonzero(res.fallback)
            res.actions[fb] = offenders_wait(self.layout.next_cell, self.layout.move_valid, pos[fb],
                                             occ[fb], ctl[fb], prop[fb], blocked[fb])
        dec.actions = np.where(controlled, gs.scatter(res.actions.reshape(b, z, -1), core.n), WAIT)
        dec.candidates = res.examined.reshape(b, z).sum(1)
        dec.filter_calls = res.called.reshape(b, z).sum(1)
        dec.fallbacks = res.fallback.reshape(b, z).sum(1)

    def _prediction_error(self, cells: np.ndarray, link_msgs: np.ndarray, lost: np.ndarray,
                          sender_slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per episode: summed over lost links, the mean squared position error (cells^2)
        of the snapped prediction over the sender's robots on the floor; and the count."""
        true_rc = link_msgs[..., POS]
        pred_rc = self.layout.cells[cells].astype(np.float32)
        on = (link_msgs[..., PRESENT] > 0) & sender_slots[None]
        err = (((pred_rc - true_rc) ** 2).sum(-1) * on).sum(-1) / np.maximum(on.sum(-1), 1)
        return (err * lost).sum(axis=(1, 2)), lost.sum(axis=(1, 2)).astype(np.float64)

    # ---------------------------------------------------------------- update
    def learner(self) -> Learner:
        """The networks, optimizers and sizes the updates (training.py) read and step."""
        return Learner(self.params, self.gs, self.env.horizon, self.env.n_robots,
                       self.reference, self.local, self.predictor, self.critic,
                       self.opt_policy, self.opt_critic, self.opt_predictor)

    def update(self, state: Controller) -> dict[str, float]:
        assert state.buffer is not None
        learner = self.learner()
        losses = (mappo_policy_update(learner, state.buffer, self.seed, self.iterations) if self.mappo
                  else policy_update(learner, state.buffer))
        if self.params.messages == "predicted":  # else unused
            losses.update(predictor_update(learner, state.buffer))
        else:
            losses["predictor_loss"] = float("nan")
        return losses
