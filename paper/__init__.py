"""The paper's wing: the reproduction of "Hierarchical Multi-agent Reinforcement Learning for
Warehouse Robot Coordination under Communication Loss" on top of the harness.

It uses the harness the way an outside package does and registers with it in
pyproject.toml's entry-point groups: its grids (``warehouse_marl_bench.grids``: paper,
full, ablation), its report sections (``warehouse_marl_bench.report_sections``: Fig. 1-3,
Table I, the ablation, the claims of Sec. IV) and ``bench calibrate``
(``warehouse_marl_bench.commands``). Nothing below it names it (.importlinter).

Modules by role, in layers (each imports only the layers below it):

    sections | cli              the report sections; `bench calibrate`
    pages                       the claims' verdicts and checks on the index
    claims                      the claims, their tests, their page and calibration
    tables                      Table I, the ablation
    figures                     Fig. 1-3
    grids | roles | data        the grids; the method-role table; Fig. 3's payload points
    settings                    the paper's experimental settings, each stated once (every PAPER_*)

May import: envs, algorithms, bench, reports, studies.
"""
