"""Command-line tools (coverage-plan, coverage-team)."""
