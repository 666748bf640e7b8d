"""Pages: `index.html`/`index.md` of a report and the shared layout.

May import: envs, algorithms, bench, reports.tables, reports.writers, reports.figures,
reports.data, reports.stats (the layers of .importlinter).
"""
