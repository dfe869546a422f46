"""Motion of the human: retargeting, the reference motion, kinematic replay, synthetic walks."""
