"""The planning methods' names (a light module: the CLI validates options without loading the solvers)."""

METHODS = ("chnn-ga", "chnn", "exact", "auto")
