"""Interop tests run the recipes of docs/interop.md; the libraries are in the dev extra."""
from __future__ import annotations

import torch


def pytest_configure(config):
    torch.set_num_threads(1)
