"""The paper's Fig. 1-3, drawn with the report's shared look (reports.figures)."""
