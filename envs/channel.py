"""The lossy inter-group channel: fixed groups, availability A_t, payload accounting.

* Groups (Assumption 1): robot i belongs to group i mod Z, fixed over the episode.
* Messages (eq:message): M_t^{z',z} = (X_t^{z'}, U_{t-1}^{z'}); d_m scalars per robot.
* Availability A_t^{z',z}: i.i.d. Bernoulli(1 - p) per directed link and step, or a
  Gilbert-Elliott two-state chain per link with the same mean loss p (bursty; beyond
  the paper). Loss affects only links between different groups (Assumption 3).
* Payload (Sec. III-A): C_hier = sum over directed links of the scalars sent
  (= N (Z-1) d_m on the complete graph), C_dec = N (N-1) d_m.

The environment owns the channel (SPEC 2 "Communication"): ``open_channel`` is the one
place a channel is built, between groups (the paper's hierarchy) or between robots (the
all-to-all baselines), for the PettingZoo adapter and for every method alike
(``EpisodeBatch.open_channel``); methods read what it delivered. Nothing outside
``envs/`` constructs a ``LossProcess`` or a ``Channel`` (tests/envs/test_channel_owner.py).
"""
from __future__ import annotations

import numpy as np

from envs.config import EnvConfig


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
    (P(Good -> Bad) > 1): ``EnvConfig`` refuses it where the value enters
    (``envs.config.loss_error``, the one loss rule), so the values here are valid.
    """

    def __init__(
        self, link_shape: tuple[int, ...], p: float, rng: np.random.Generator,
        model: str = "bernoulli", burst_length: float = 4.0,
    ) -> None:
        self.shape, self.p, self.rng, self.model = link_shape, float(p), rng, model
        if model == "gilbert_elliott":
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


class DelayLine:
    """Message delay on a set of directed links, shaped ``link_shape`` (beyond the paper).

    Every link carries one message per step; the message of step t that the loss process
    delivers arrives at step t + d, with d = ``mean`` for ``model="fixed"`` or d drawn per
    message from a geometric law on {0, 1, ...} with that mean for ``"geometric"``, cut to
    ``bound``. A lost message never arrives. A receiver keeps the freshest message it got on
    each link: ``sent_at`` is its send step (-1: none yet), so its age at step t is
    t - ``sent_at``; an older message arriving after a newer one is dropped. The delays
    are drawn from their own generator, so the loss pattern is that of delay 0.
    """

    def __init__(self, link_shape: tuple[int, ...], mean: float, model: str, bound: int,
                 rng: np.random.Generator | None) -> None:
        if model not in ("fixed", "geometric"):
            raise ValueError(f"unknown delay model {model!r}")
        if model == "geometric" and rng is None:
            raise ValueError("a geometric delay needs a generator")
        self.shape, self.mean, self.model, self.bound, self.rng = link_shape, float(mean), model, int(bound), rng
        self.slots = self.bound + 1  # arrivals are at most ``bound`` steps ahead
        self.pending = np.full((self.slots, *link_shape), -1, dtype=np.int64)  # send step by arrival slot
        self.sent_at = np.full(link_shape, -1, dtype=np.int64)
        self.t = 0  # steps so far: the send step of the next message
        self._links = np.indices(link_shape).reshape(len(link_shape), -1)

    def delays(self) -> np.ndarray:
        """This step's delay of every link's message, shaped ``link_shape``."""
        if self.model == "fixed":
            return np.full(self.shape, int(self.mean), dtype=np.int64)
        assert self.rng is not None
        # Inverse CDF of P(d >= k) = q^k, q = mean / (1 + mean), from uniform draws only (so a
        # stack of generators, one per part's episodes, draws each part's own delays).
        u = self.rng.random(self.shape)
        d = np.floor(np.log1p(-u) / np.log(self.mean / (1.0 + self.mean)))
        return np.minimum(d, self.bound).astype(np.int64)

    def step(self, delivered: np.ndarray) -> np.ndarray:
        """Send this step's messages (``delivered``: not lost); returns where a message
        fresher than the one held arrived this step (``sent_at`` is then its send step)."""
        t, d = self.t, self.delays()
        arrival = (t + d) % self.slots
        ok = delivered.reshape(-1)
        # t is the newest send step: it overwrites any older message due the same step.
        self.pending[(arrival.reshape(-1)[ok], *self._links[:, ok])] = t
        now = t % self.slots
        arrived = self.pending[now].copy()
        self.pending[now] = -1
        newer = arrived > self.sent_at
        np.copyto(self.sent_at, arrived, where=newer)
        self.t += 1
        return newer


LEVELS = ("groups", "robots")  # the endpoints of a channel's links


class Channel:
    """Directed links of B episodes between endpoints (groups or robots): ``step()`` gives
    A_t shaped (B, K, K) as [b, sender, receiver], K = Z groups or N robots.

    ``level="groups"``: the paper's inter-group links on ``comm_graph``; ``"robots"``:
    every ordered pair of distinct robots (the all-to-all baselines). The loss process is
    drawn over the whole (B, K, K) array, diagonal included, so the stream of draws is
    the same whatever the graph.

    With a delay (``config.delay > 0``, ``DelayLine``) ``step()`` still gives the
    messages of this step that arrive this step (a delayed message is not available when
    it is sent, like a lost one); ``arrived`` marks where a fresher message than the one
    held came in, ``sent_at`` its send step (the age of what a receiver holds at step t
    is t - ``sent_at``). Without a delay ``arrived`` is ``step()``'s result and
    ``sent_at`` None (no extra work).
    """

    def __init__(self, config: EnvConfig, batch: int, rng: np.random.Generator,
                 level: str = "groups") -> None:
        n = config.n_robots
        if level == "groups":
            k = config.groups
            self.adjacency = comm_graph(k, config.comm_graph)  # (Z, Z)
        elif level == "robots":
            k = n
            self.adjacency = ~np.eye(n, dtype=bool)
        else:
            raise ValueError(f"unknown channel level {level!r}; use one of {', '.join(LEVELS)}")
        self.level = level
        self.groups = group_assignment(n, config.groups)
        self.group_sizes = np.bincount(self.groups, minlength=config.groups)  # (Z,)
        self.process = LossProcess.from_config((batch, k, k), config, rng)
        self.delay: DelayLine | None = None
        if config.delay > 0:  # its own generator: the loss draws stay those of delay 0
            own = rng.spawn(1)[0] if config.delay_model == "geometric" else None
            self.delay = DelayLine((batch, k, k), config.delay, config.delay_model, config.delay_max, own)
        self.arrived = np.zeros((batch, k, k), dtype=bool)
        self.d_m = config.d_m
        # Scalars transmitted per step: every sender group's robots on each outgoing link.
        group_adj = self.adjacency if level == "groups" else comm_graph(config.groups, config.comm_graph)
        self.payload_hier = int((group_adj.sum(axis=1) * self.group_sizes).sum() * self.d_m)
        self.payload_dec = n * (n - 1) * self.d_m

    def step(self) -> np.ndarray:
        """(B, K, K) bool availability of this step's messages now; False on non-edges and
        the diagonal."""
        delivered = self.process.step() & self.adjacency[None]
        if self.delay is None:
            self.arrived = delivered
            return delivered
        self.arrived = self.delay.step(delivered)
        return self.arrived & (self.delay.sent_at == self.delay.t - 1)

    @property
    def sent_at(self) -> np.ndarray | None:
        """(B, K, K) send step of the freshest message held on each link (-1: none), or
        None without a delay (the held message of a link is then its last delivered one)."""
        return None if self.delay is None else self.delay.sent_at


class GroupChannel(Channel):
    """The inter-group channel (``Channel`` with ``level="groups"``)."""

    def __init__(self, config: EnvConfig, batch: int, rng: np.random.Generator) -> None:
        super().__init__(config, batch, rng, "groups")


def open_channel(config: EnvConfig, batch: int, rng: np.random.Generator,
                 level: str = "groups") -> Channel:
    """The environment's channel of ``batch`` episodes at ``level``, its draws from ``rng``
    (every random number of the channel comes from it, in step order)."""
    return GroupChannel(config, batch, rng) if level == "groups" else Channel(config, batch, rng, level)
