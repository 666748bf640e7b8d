"""The lossy inter-group channel: fixed groups, availability A_t, payload accounting.

* Groups (Assumption 1): robot i belongs to group i mod Z, fixed over the episode.
* Messages (eq:message): M_t^{z',z} = (X_t^{z'}, U_{t-1}^{z'}); d_m scalars per robot.
* Availability A_t^{z',z}: i.i.d. Bernoulli(1 - p) per directed link and step, or a
  Gilbert-Elliott two-state chain per link with the same mean loss p (bursty; beyond
  the paper). Loss affects only links between different groups (Assumption 3).
* Payload (Sec. III-A): C_hier = sum over directed links of the scalars sent
  (= N (Z-1) d_m on the complete graph), C_dec = N (N-1) d_m.
"""
from __future__ import annotations

import numpy as np

from envs.config import EnvConfig, bursty_loss_error


def group_assignment(n_robots: int, n_groups: int) -> np.ndarray:
    """(N,) group index of each robot: robot i in group i mod Z (sizes differ by <= 1)."""
    return np.arange(n_robots, dtype=np.int64) % n_groups


def group_members(n_robots: int, n_groups: int) -> np.ndarray:
    """(Z, n_max) robot indices per group, padded with -1."""
    groups = group_assignment(n_robots, n_groups)
    n_max = int(np.bincount(groups, minlength=n_groups).max())
    out = np.full((n_groups, n_max), -1, dtype=np.int64)
    for z in range(n_groups):
        members = np.flatnonzero(groups == z)
        out[z, : len(members)] = members
    return out


def comm_graph(n_groups: int, kind: str = "complete") -> np.ndarray:
    """(Z, Z) bool adjacency: ``adj[z', z]`` is True if z' may transmit to z."""
    if kind == "complete":
        adj = np.ones((n_groups, n_groups), dtype=bool)
    elif kind == "ring":
        adj = np.zeros((n_groups, n_groups), dtype=bool)
        z = np.arange(n_groups)
        adj[(z - 1) % n_groups, z] = True
        adj[(z + 1) % n_groups, z] = True
    else:
        raise ValueError(f"unknown comm_graph {kind!r}")
    np.fill_diagonal(adj, False)
    return adj


class LossProcess:
    """Availability of a set of directed links, shaped ``link_shape``, step by step.

    ``bernoulli``: each link and step is lost independently with probability p.
    ``gilbert_elliott``: each link is a two-state Markov chain (Good: delivered, Bad: lost)
    with P(Good -> Bad) = p / (burst (1 - p)) and P(Bad -> Good) = 1 / burst, so the
    stationary loss rate is p and bad runs last ``burst`` steps on average. The chain
    starts in its stationary distribution. A p above burst / (burst + 1) has no such chain
    (P(Good -> Bad) > 1) and is refused, never quietly lowered.
    """

    def __init__(
        self, link_shape: tuple[int, ...], p: float, rng: np.random.Generator,
        model: str = "bernoulli", burst_length: float = 4.0,
    ) -> None:
        self.shape, self.p, self.rng, self.model = link_shape, float(p), rng, model
        if model == "gilbert_elliott":
            why = bursty_loss_error(self.p, burst_length)
            if why is not None:
                raise ValueError(f"gilbert_elliott loss: {why}")
            self.p_bg = 1.0 / burst_length
            # min: p at the limit L / (L + 1) gives 1 up to rounding
            self.p_gb = min(1.0, p * self.p_bg / (1.0 - p)) if p < 1.0 else 1.0
            self.bad = rng.random(link_shape) < p
        elif model != "bernoulli":
            raise ValueError(f"unknown loss model {model!r}")

    @classmethod
    def from_config(cls, link_shape: tuple[int, ...], config: EnvConfig,
                    rng: np.random.Generator) -> LossProcess:
        """The loss model, mean loss p and burst length of an environment config."""
        return cls(link_shape, config.loss_p, rng, config.loss_model, config.burst_length)

    def step(self) -> np.ndarray:
        """Bool array shaped ``link_shape``: True where this step's message arrives."""
        u = self.rng.random(self.shape)
        if self.model == "bernoulli":
            return u >= self.p
        if self.p >= 1.0:
            self.bad[...] = True
        else:
            self.bad = np.where(self.bad, u >= self.p_bg, u < self.p_gb)
        return ~self.bad


class GroupChannel:
    """Inter-group links of B episodes: ``step()`` gives A_t shaped (B, Z, Z) as [b, z', z]."""

    def __init__(self, config: EnvConfig, batch: int, rng: np.random.Generator) -> None:
        z = config.groups
        self.adjacency = comm_graph(z, config.comm_graph)  # (Z, Z)
        self.groups = group_assignment(config.n_robots, z)
        self.group_sizes = np.bincount(self.groups, minlength=z)  # (Z,)
        self.process = LossProcess.from_config((batch, z, z), config, rng)
        self.d_m = config.d_m
        n = config.n_robots
        # Scalars transmitted per step: every sender group's robots on each outgoing link.
        self.payload_hier = int((self.adjacency.sum(axis=1) * self.group_sizes).sum() * self.d_m)
        self.payload_dec = n * (n - 1) * self.d_m

    def step(self) -> np.ndarray:
        """(B, Z, Z) bool availability; False on non-edges and the diagonal."""
        return self.process.step() & self.adjacency[None]
