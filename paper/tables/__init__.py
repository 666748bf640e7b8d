"""The paper's Table I (the safety filter) and the ablation of its method."""
