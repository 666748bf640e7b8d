"""What every learned method shares: the paper's trainer, batched episodes and execution
modes, robot-level observations and messages, seed stacking and the observer hook."""
