"""gaitloop metrics: the paper's tables (compliance, gait, stability), range of motion, harness
forces and SPM1D comparisons, each a pure function of tidy tables returning tidy tables.

Import from the modules (`metrics.spm`, `metrics.gait`, ...): this package root imports none of
them, so a stage runs, and its dvc.yaml deps name, only the metrics modules it uses."""
