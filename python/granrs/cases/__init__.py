"""Ready-made cases with their outputs and plots (``granrs run CASE``)."""
