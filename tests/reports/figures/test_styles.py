"""The report's method table (reports/figures/styles.py): the built-ins' look comes from the
table the paper's wing registers (the same colours, line styles and ranks the committed
figures use); a plugin that still declares its look on the Method class keeps it with a
DeprecationWarning; any other method gets a stable default from the palette."""
from __future__ import annotations

import warnings

import pytest

from algorithms import registry
from algorithms.base import UNRANKED
from reports.figures import styles
from reports.figures.styles import DEFAULT_PALETTE, Style, method_style_of
from tests.bench.toy_method import TOY_PATH, ToyMethod

# The look of the committed figures, written out by hand.
BUILT_INS = {"hierarchical": Style("#0173b2", "-", 0), "decentralized": Style("#de8f05", "--", 1),
             "ic3net": Style("#029e73", "-.", 2), "pibt": Style("#949494", ":", 3)}


def test_built_ins__from_the_registered_table_without_a_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert {m: method_style_of(m) for m in BUILT_INS} == BUILT_INS


class OldPlugin(ToyMethod):
    """A plugin written against the older contract: its look on the class."""

    color = "#123456"
    line_style = "--"
    legend_rank = 7


def test_old_plugin__keeps_its_look_with_a_deprecation_warning() -> None:
    method_style_of.cache_clear()
    registry.register("oldplugin", f"{__name__}:OldPlugin")
    try:
        with pytest.warns(DeprecationWarning, match="warehouse_marl_bench.styles"):
            assert method_style_of("oldplugin") == Style("#123456", "--", 7)
    finally:
        registry.unregister("oldplugin")
        method_style_of.cache_clear()


def test_any_other_method__a_stable_default_from_the_palette() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the toy declares no look: no warning
        got = method_style_of(TOY_PATH)
        assert got == method_style_of(TOY_PATH) and got.color in DEFAULT_PALETTE
        assert got.line_style == "-" and got.rank == UNRANKED
        assert method_style_of("not_installed_anywhere").color in DEFAULT_PALETTE


def test_a_method_styled_twice_differently_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    class EP:
        def __init__(self, table: dict[str, Style]) -> None:
            self.table, self.value = table, "x:TABLE"

        def load(self) -> dict[str, Style]:
            return self.table

    monkeypatch.setattr(styles.metadata, "entry_points",
                        lambda group: [EP({"m": Style("#000000")}), EP({"m": Style("#ffffff")})])
    styles.registered_styles.cache_clear()
    try:
        with pytest.raises(Exception, match="two styles"):
            styles.registered_styles()
    finally:
        monkeypatch.undo()
        styles.registered_styles.cache_clear()
