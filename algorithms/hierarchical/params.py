"""HierarchicalParams: the hierarchical method's hyperparameters (a pydantic model).

Its own module so that the method (``method.py``) and its updates (``training.py``) both
read it without importing each other. May import: algorithms.base, algorithms.presets, pydantic.
"""
from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import Field

from algorithms.base import LearnedParams
from algorithms.presets import Preset

# Named presets beside the paper's defaults (algorithms/presets.py): "tuned" is the winner
# of the committed study reproduction/studies/tuned-hierarchical (decisions 0215, 0246);
# tests/studies/test_published_presets.py checks these values against it.
PRESETS = {"tuned": Preset({"protocol": "mappo", "ref_size": 8, "search_radius": 3, "c_max": 1000,
                            "share_params": True, "fallback": "per_robot", "resample_on_fallback": True,
                            "ref_hold": 10, "ppo_lr": 0.001, "entropy_coef": 0.03},
                           source="studies/definitions/hierarchical.toml")}


class HierarchicalParams(LearnedParams):
    """Hyperparameters of the hierarchical method (defaults: docs/decisions/0101-0118, 0126)."""

    added_later: ClassVar[tuple[str, ...]] = (*LearnedParams.added_later, "local_credit")

    batch_episodes: int = Field(8, ge=1, description="episodes per update, batched in one process")
    ref_size: int = Field(8, ge=1, description="|R_z|, size of the abstract reference space")
    search_radius: int = Field(2, ge=0, description="safety filter search radius L")
    c_max: int = Field(500, ge=1, description="safety filter candidate budget C_max")
    safety_filter: bool = Field(True, description="run Algorithm 1 before execution")
    predictor_hidden: int = Field(64, ge=4, description="GRU hidden size per link")
    predictor_embed: int = Field(32, ge=4, description="message embedding width of the predictor")
    obs_radius: int = Field(2, ge=1, description="half-width k of the (2k+1)^2 local patches")
    predictor_lr: float = Field(1e-3, gt=0, description="Adam learning rate of the GRU predictors")
    share_params: bool = Field(False, description="one parameter set for all groups (paper: per group)")
    update_chunk: int = Field(128, ge=1, description="time steps per backward pass in the update")
    # Variants beyond the paper (docs/decisions/0118; defaults are the paper's).
    messages: Literal["predicted", "oracle", "last"] = Field(
        "predicted", description="S-hat on lost links: GRU prediction (paper), ground truth "
        "(oracle upper bound) or the last received message (no predictor)")
    fallback: Literal["joint", "per_robot"] = Field(
        "joint", description="when no candidate is admissible: joint Wait (Alg. 1 line 12) or "
        "only the offending robots wait")
    resample_on_fallback: bool = Field(
        False, description="argmax execution: a group that fell back samples a new proposal once "
        "and is filtered again")
    ref_hold: int = Field(1, ge=1, description="steps a sampled reference r is held (paper: 1, "
                          "r is drawn every step)")
    ref_lr: float | None = Field(None, gt=0, description="Adam learning rate of mu (None: lr)")
    ref_entropy_coef: float | None = Field(
        None, ge=0, description="entropy bonus on mu (None: entropy_coef)")
    ref_embed_scale: float = Field(0.5, ge=0, description="init std of the reference embedding in pi")
    local_credit: Literal["group", "credit"] = Field(
        "group", description="mappo: the credit of pi's per-robot factors: their group's advantage "
        "(the joint-Wait fallback couples a group's robots) or the shared `credit` (robot or team)")
    ref_advantage: Literal["team", "group"] = Field(
        "team", description="advantage weighing log mu(r^z): the team's (eq:advantage) or group z's "
        "own return minus its share n_z/N of V")
