"""Tools built on the pipeline: the oracle and the metrics, studies, stability, batches, sweeps, comparison, the live view."""
