"""Tools built on the pipeline: the oracle, metrics, studies, stability, batches, sweeps, comparison, the live view."""
