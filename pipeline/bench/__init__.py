"""`python -m pipeline bench`: speed and memory targets as ratios measured in one run."""

# bench.json sections, in run order
SECTIONS = ("ingest", "retarget", "human", "store", "rollout", "policy_rollout", "sweep", "train", "transfer")
