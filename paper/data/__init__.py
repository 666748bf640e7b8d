"""The paper's data points derived from a run's rows (Fig. 3's payload)."""
