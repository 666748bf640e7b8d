"""The bench's Method contract, run against both example methods (by their entry-point
names, so the test also checks that the package is installed and registered)."""
from algorithms.testing import MethodContract


class TestGreedy(MethodContract):
    method = "greedy"


class TestLinear(MethodContract):
    method = "linear"
