"""``kinmo prepare``: read dataset folders into part-graph caches."""
