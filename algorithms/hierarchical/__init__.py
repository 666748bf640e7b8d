"""algorithms/hierarchical."""
