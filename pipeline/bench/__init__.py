"""`python -m pipeline bench`: speed and memory targets as ratios measured in one run."""
