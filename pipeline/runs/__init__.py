"""What stages and commands both run, below both: the batch runner's setups and jobs (`jobs`),
evaluate-policy (`evaluate_policy`), the transfer gate (`gate`) and the per-subject controller tuning
(`tune`, the command `tune`'s engine). Stages and commands import from here; nothing here imports a
stage or a command (tests/test_architecture.py checks that a stage imports no command and that no
import cycle forms)."""
