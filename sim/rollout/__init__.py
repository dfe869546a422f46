"""Closed-loop rollouts: world assembly, the one rollout loop, the batch runner, controller tuning."""
