"""`python -m pipeline bench`: speed and memory targets as ratios measured in one run."""

SECTIONS = ("ingest", "retarget", "human", "store", "rollout", "train")  # bench.json sections, in run order
