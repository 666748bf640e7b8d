"""Two example methods for warehouse-marl-bench, registered through entry points:
``greedy`` (a planner) and ``linear`` (a learned per-robot linear softmax policy)."""
