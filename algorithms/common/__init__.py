"""algorithms/common."""
