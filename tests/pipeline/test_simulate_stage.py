"""Stage `simulate <subject>` (pipeline/stages/simulate.py) on camargo's scaled model and reference
(built by the stages in conftest's `camargo_model`): the replay-human rollouts of every straight bout,
condition and seed, and the tracking figure."""

from __future__ import annotations

from pipeline.stages.simulate import run_simulate


def test_camargo_simulate_reproduces_the_paper_table1_ordering(params, camargo_model, tmp_path):
    """`simulate camargo` (replay human, straight bouts, every seed): the adaptive controller has
    lower mean |e_x|, mean |e_y| and harness force RMS than the PID (ICRA 2025 Table I), both tuned
    by the same procedure on synthetic walks only; no rollout unstable or warned, no fall."""
    root = camargo_model.parent.parent
    doc = run_simulate("camargo", params, root, tmp_path, progress=False)
    assert doc["unstable"] == 0 and doc["warnings"] == []
    pid, adaptive = doc["conditions"]["pid"], doc["conditions"]["adaptive"]
    assert pid["falls"] == adaptive["falls"] == 0
    for key in ("mean_abs_e_x_cm", "mean_abs_e_y_cm", "harness_force_rms_n"):
        assert adaptive[key] < pid[key], key
    assert 1.0 < pid["mean_abs_e_x_cm"] < 15.0
    assert (tmp_path / "camargo" / "robot_tracking.png").stat().st_size > 10_000
