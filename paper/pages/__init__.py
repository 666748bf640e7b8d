"""The claims' verdicts and grouped checks on the report's index page."""
