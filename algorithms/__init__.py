"""The methods: the contract every method implements and the built-in methods behind it.

* ``base.py``: the ``Method`` contract (train, evaluate, checkpoint, declare traits);
  ``registry.py``: the one place a method name is resolved (built-ins, entry points,
  ``module:Class``); ``testing.py``: the contract suite a user's package runs;
* ``hierarchical/``: the paper's method (groups, the message predictor, the reference and
  local policies, the safety filter); ``decentralized.py``, ``ic3net.py``: the learned
  baselines; ``pibt.py``: the PIBT planner (full information);
* ``common/``: what the learned methods share (trainer, episodes, execution modes, robot
  observations, all-to-all messages, seed stacking, the observer hook).
"""
