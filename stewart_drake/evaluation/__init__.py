"""Every controller on every task side by side, with the cost declared before any run:
``stewart-drake evaluate`` and its report (docs/results.md)."""
