"""The report's "Virtual cohort" and "Fall intervention" sections and their figures, from small
frames shaped like the store's views (`cohort_gait`, `cohort_controllers`, `fall_intervention`,
`falls_not_caught`, `false_alarms` of pipeline/store/views/), and the published clinical ranges they
are read beside (data/paper/clinical_ranges.yaml). The whole path from a store is in test_report.py."""

import math

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from metrics.plots import COHORT_PANELS, FALL_PANELS, VARIANT_ORDER, cohort_heatmap, fall_intervention_figure
from pipeline.report import sections
from pipeline.report.figures import FIGURES, figure_names
from pipeline.report.published import CLINICAL_MEASURES, PaperError, load_clinical_ranges
from pipeline.report.render import section_markdown
from pipeline.runs.studies import report_params

NAN = math.nan
NO_COHORT = ("No cohort walks stored for this subject yet (run the sweep studies, `python -m pipeline sweep` "
             "and `python -m pipeline sweep --study fall_intervention`, then `store`).")
NO_FALLS = ("No fall-intervention rollouts stored for this subject yet (run `python -m pipeline sweep "
            "--study fall_intervention`, then `store`).")
CAUGHT_DROP_M = 0.22
WINDOW_S = 1.5
GAIT = ["subject", "variant", "scenario", "walks", "distinct_walks", "falls", "gait_speed_mps",
        "gait_speed_sd", "stride_length_m", "stance_ratio_lr", "swing_ratio_lr", "stride_time_cv_pct",
        "strides", "status"]
CONTROLLERS = ["subject", "variant", "condition", "scenario", "walks", "falls", "mean_abs_ex_cm",
               "mean_abs_ey_cm", "force_rms_n", "speed_change_pct", "stride_change_pct", "cv_change_pct"]
FALL = ["subject", "variant", "event", "condition", "rollouts", "fell_before_onset", "events",
        "events_falling_free", "human_falls", "detection_rate", "detection_rate_falling",
        "caught_rate_falling", "latency_s", "pelvis_drop_at_lock_m", "worst_drop_at_lock_m",
        "max_harness_force_n", "peak_harness_force_n"]
NOT_CAUGHT = ["subject", "variant", "event", "condition", "scenario", "seed", "onset_s", "human_fall_s",
              "robot_fall_s", "latency_s", "pelvis_drop_at_lock_m", "reason"]
ALARMS = ["subject", "variant", "condition", "rollouts", "walking_h", "alarms", "false_alarms",
          "false_alarms_per_h"]


def gait_frame() -> pd.DataFrame:
    """healthy and a left hemiparetic variant walking free; the hemiparetic one has no stance ratio
    (no toe-off found on one side) and fell once in walk_10m, where its 4 walks are 2 distinct ones."""
    return pd.DataFrame([
        ["s1", "hemiparetic_left", "steady", 4, 4, 0, 0.71, 0.02, 0.82, 1.12, 0.78, 4.1, 60, "walked"],
        ["s1", "healthy", "steady", 4, 4, 0, 1.31, 0.01, 1.36, 1.01, 0.99, 1.4, 80, "walked"],
        ["s1", "hemiparetic_left", "walk_10m", 4, 2, 1, 0.69, NAN, 0.80, NAN, 0.80, 4.5, 30, "fell"],
    ], columns=GAIT)


def controllers_frame() -> pd.DataFrame:
    """Three variants with pid and adaptive in steady and walk_10m; weak's adaptive gait speed change is
    missing (no free walk to compare with)."""
    rows = []
    for k, variant in enumerate(("weak", "healthy", "hemiparetic_left")):
        for j, cond in enumerate(("adaptive", "pid")):
            for scenario in ("steady", "walk_10m"):
                speed = NAN if (variant, cond) == ("weak", "adaptive") else -1.5 * (k + 1) + j
                rows.append(["s1", variant, cond, scenario, 4, 0, 0.4 + 0.3 * j + 0.1 * k, 1.1 + 0.1 * k,
                             22.0 + 2 * j + k, speed, -1.0, 0.2])
    return pd.DataFrame(rows, columns=CONTROLLERS)


def fall_frame() -> pd.DataFrame:
    """healthy: trip and push, free and both controllers; weak: a trip without free walks, pid only,
    never detected (latency, drops and caught rates NULL)."""
    return pd.DataFrame([
        ["s1", "healthy", "trip", "free", 4, 0, 4, 4, 4, 0.0, 0.0, 0.0, NAN, NAN, NAN, NAN, NAN],
        ["s1", "healthy", "trip", "pid", 4, 0, 4, 4, 0, 1.0, 1.0, 1.0, 0.21, 0.04, 0.08, 900.0, 1200.0],
        ["s1", "healthy", "trip", "adaptive", 4, 1, 3, 3, 0, 1.0, 1.0, 0.67, 0.25, 0.09, 0.25, 950.0, 1500.0],
        ["s1", "healthy", "push", "free", 4, 0, 4, 2, 2, 0.0, 0.0, 0.0, NAN, NAN, NAN, NAN, NAN],
        ["s1", "healthy", "push", "pid", 4, 0, 4, 2, 1, 0.5, 0.5, 0.5, 0.6, 0.02, 0.03, 700.0, 800.0],
        ["s1", "weak", "trip", "pid", 2, 0, 2, 0, 2, 0.0, NAN, NAN, NAN, NAN, NAN, 300.0, 310.0],
    ], columns=FALL)


def not_caught_frame() -> pd.DataFrame:
    """One uncaught fall per reason (listed out of order): healthy's trip caught too low with adaptive
    and its push never detected with pid (as in `fall_frame`), then with adaptive a push locked too late,
    one before its onset, one the human fell before, and one unstable."""
    return pd.DataFrame([
        ["s1", "healthy", "push", "adaptive", "walk_10m", 0, 3.0, 4.1, 5.2, 2.2, 0.06, "not_detected"],
        ["s1", "healthy", "push", "adaptive", "steady", 2, 3.0, NAN, 2.5, NAN, NAN, "locked_before_onset"],
        ["s1", "healthy", "push", "adaptive", "steady", 3, 3.0, NAN, NAN, NAN, NAN, "unstable"],
        ["s1", "healthy", "push", "adaptive", "steady", 1, 3.0, 2.1, 2.05, NAN, NAN, "fell_before_onset"],
        ["s1", "healthy", "push", "pid", "steady", 1, 3.0, 3.9, NAN, NAN, NAN, "not_detected"],
        ["s1", "healthy", "trip", "adaptive", "steady", 2, 3.0, 3.9, 3.25, 0.25, 0.25, "dropped"],
    ], columns=NOT_CAUGHT)


def alarms_frame() -> pd.DataFrame:
    return pd.DataFrame([["s1", "healthy", "pid", 8, 0.02, 1, 1, 50.0],
                         ["s1", "healthy", "adaptive", 8, 0.021, 0, 0, 0.0],
                         ["s1", "weak", "pid", 2, 0.0, 0, 0, NAN]], columns=ALARMS)


def panel_axes(fig: Figure) -> list:
    """The figure's panels, without colour bars."""
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]


def texts(ax) -> list[str]:
    return [t.get_text() for t in ax.texts]


# -- figures ------------------------------------------------------------------------------------------


def test_cohort_heatmap_has_one_panel_and_colour_scale_per_metric():
    fig = cohort_heatmap(controllers_frame(), "s1: cohort", ("pid", "adaptive"))  # the caller's order
    panels = panel_axes(fig)
    assert [ax.get_title() for ax in panels] == [title for title, _ in COHORT_PANELS.values()]
    assert len(fig.axes) == 2 * len(COHORT_PANELS)  # a colour bar beside every panel
    assert fig._suptitle.get_text() == "s1: cohort, scenario steady"
    for ax in panels:  # rows: variants, healthy first; columns: controllers
        assert [t.get_text() for t in ax.get_yticklabels()] == ["healthy", "weak", "hemiparetic_left"]
        assert [t.get_text() for t in ax.get_xticklabels()] == ["pid", "adaptive"]
        assert len(ax.texts) == 6
    ex, speed = panels[0], panels[3]
    assert texts(ex)[:2] == ["0.80", "0.50"]  # healthy: pid, adaptive
    assert texts(speed)[3] == "–"  # weak, adaptive: no free walk to compare with
    assert speed.images[0].get_clim() == (-4.5, 4.5)  # diverging, centred on no change


def test_cohort_heatmap_takes_the_scenario_there_is_and_survives_no_rows():
    only = controllers_frame().query("scenario == 'walk_10m'")
    assert cohort_heatmap(only, "t")._suptitle.get_text() == "t, scenario walk_10m"
    empty = cohort_heatmap(controllers_frame().iloc[0:0], "t")
    assert len(panel_axes(empty)) == len(COHORT_PANELS)
    assert all(texts(ax) == ["no cohort walks with a robot"] for ax in empty.axes)


def test_fall_figure_has_a_row_of_panels_per_variant():
    fig = fall_intervention_figure(fall_frame(), "s1: falls", 0.22, ("pid", "adaptive"))
    axes = fig.axes
    assert len(axes) == 2 * len(FALL_PANELS)  # healthy, weak
    labels = list(FALL_PANELS.values())
    assert [ax.get_title() for ax in axes] == [f"{v}: {lab}" for v in ("healthy", "weak") for lab in labels]
    assert [t.get_text() for t in axes[0].get_xticklabels()] == ["trip", "push"]
    drop = axes[2]
    assert [ln.get_ydata()[0] for ln in drop.get_lines() if ln.get_linestyle() == "--"] == [0.22]
    assert len(axes[0].patches) == 4  # pid and adaptive over trip and push; no bar for free
    weak_latency = axes[len(FALL_PANELS) + 1]
    assert texts(weak_latency) == ["–", "–", "–", "–"]  # never detected; no adaptive rows at all
    assert texts(axes[len(FALL_PANELS)]) == ["0", "–", "–", "–"]  # detected: 0 of its trips, a dash elsewhere
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert {"pid", "adaptive", "caught threshold 0.22 m"} <= set(legend) and "free" not in legend


def test_fall_figure_without_robot_rows_says_so():
    for frame in (fall_frame().iloc[0:0], fall_frame().query("condition == 'free'")):
        fig = fall_intervention_figure(frame, "t", CAUGHT_DROP_M)
        assert len(fig.axes) == len(FALL_PANELS)
        assert all(texts(ax) == ["no rollouts with a robot"] for ax in fig.axes)


# -- sections -----------------------------------------------------------------------------------------


def cohort_text(*args, **kwargs) -> str:
    return section_markdown("cohort", sections.cohort(*args, **kwargs))


def fall_text(*args) -> str:
    return section_markdown("fall", sections.fall(*args))


def test_cohort_section_prints_the_gait_beside_the_clinical_ranges():
    ranges = load_clinical_ranges()
    text = cohort_text(gait_frame(), controllers_frame(), ranges, figure=True)
    assert text.startswith("## Virtual cohort")
    assert "| healthy | steady | 4 | 0/4 | 1.310 ± 0.010 | 1.360 | 1.010 | 0.990 | 1.40 | 80 |" in text
    # no SD across walks, no stance ratio: dashes, the rest still printed
    assert ("| hemiparetic_left | walk_10m | 4 (2 distinct) | 1/4 | 0.690 | 0.800 | – | 0.800 | 4.50 | 30 |"
            in text)
    assert text.index("| healthy | steady | 4") < text.index("| hemiparetic_left | steady")
    assert "missing from these tables: here hemiparetic_right, slow, unsteady." in text
    for r in ranges.values():
        assert f"| {CLINICAL_MEASURES[r.measure]} | {r.value_text()} | {r.meaning} | {r.source} |" in text
    assert "| weak | steady | adaptive | 4 | 0/4 | 0.40 | 1.10 | 22.00 | – | -1.00 | 0.20 |" in text
    assert "![cohort](figures/cohort.png)" in text
    assert "![cohort]" not in cohort_text(gait_frame(), controllers_frame(), ranges, figure=False)


def test_cohort_section_names_the_variants_without_a_measured_stride():
    """A variant-scenario `cohort_gait` marks `no_strides` is named; one whose walks
    fell is not (its falls say what happened), and a cohort that walked gets no such line."""
    assert "No stride measured" not in cohort_text(gait_frame(), controllers_frame(), {}, False)
    idle = pd.DataFrame([
        ["s1", "hemiparetic_right", "walk_10m", 2, 1, 0, NAN, NAN, NAN, NAN, NAN, NAN, 0, "no_strides"],
        ["s1", "unsteady", "walk_10m", 2, 2, 2, NAN, NAN, NAN, NAN, NAN, NAN, 0, "fell"],
        ["s1", "hemiparetic_right", "steady", 2, 1, 0, NAN, NAN, NAN, NAN, NAN, NAN, 0, "no_strides"],
    ], columns=GAIT)
    text = cohort_text(pd.concat([gait_frame(), idle]), controllers_frame(), {}, False)
    assert "**No stride measured:** hemiparetic_right in steady, hemiparetic_right in walk_10m: walks" in text
    assert "unsteady in walk_10m" not in text


def test_cohort_section_without_rows_says_how_to_get_them():
    text = cohort_text(gait_frame().iloc[0:0], controllers_frame().iloc[0:0], load_clinical_ranges(), False)
    assert text == f"## Virtual cohort\n\n{NO_COHORT}\n\n"
    only_gait = cohort_text(gait_frame(), controllers_frame().iloc[0:0], {}, False)
    assert "| healthy | steady | 4 |" in only_gait and "_No rows._" in only_gait


def test_fall_section_prints_each_variant_event_and_controller():
    text = fall_text(fall_frame(), not_caught_frame(), alarms_frame(), True, CAUGHT_DROP_M, WINDOW_S)
    assert text.startswith("## Fall intervention")
    rows = [line for line in text.splitlines() if line.startswith(("| healthy |", "| weak |"))]
    assert rows[:4] == [  # robot rows only, events in their usual order, pid before adaptive
        "| healthy | trip | pid | 4 | 0 | 4/4 | 0/4 | 4/4 | 0.21 | 0.040 (0.080) | 4/4 | 1200 (900) |",
        "| healthy | trip | adaptive | 3 | 1 | 3/3 | 0/3 | 3/3 | 0.25 | 0.090 (0.250) | 2/3 | 1500 (950) |",
        "| healthy | push | pid | 4 | 0 | 2/4 | 1/4 | 2/4 | 0.60 | 0.020 (0.030) | 1/2 | 800 (700) |",
        "| weak | trip | pid | 2 | 0 | – | 2/2 | 0/2 | – | – | – | 310 (300) |",  # no free walks
    ]
    assert rows[10:] == ["| healthy | pid | 8 | 0.020 | 1 | 1 | 50.00 |",
                        "| healthy | adaptive | 8 | 0.021 | 0 | 0 | 0.00 |",
                        "| weak | pid | 2 | 0.000 | 0 | 0 | – |"]
    assert f"at most {CAUGHT_DROP_M:.2f} m down" in text
    assert "missing from these tables: here hemiparetic_left, hemiparetic_right, slow, unsteady." in text
    image = f"![fall_intervention](figures/fall_intervention.png)\n\n*{FIGURES['fall_intervention']}.*"
    assert text.rstrip().endswith(image)


def test_fall_section_without_rows():
    none = not_caught_frame().iloc[0:0]
    assert fall_text(fall_frame().iloc[0:0], none, alarms_frame().iloc[0:0], False, CAUGHT_DROP_M,
                     WINDOW_S) == f"## Fall intervention\n\n{NO_FALLS}\n\n"
    alarms_only = fall_text(fall_frame().iloc[0:0], none, alarms_frame(), False, CAUGHT_DROP_M, WINDOW_S)
    assert "_No rows._" in alarms_only and "| healthy | pid | 8 | 0.020 | 1 | 1 | 50.00 |" in alarms_only


def test_falls_not_caught_are_listed_with_why_or_said_to_be_none():
    """Each uncaught fall of `falls_not_caught` in its own row, in the usual order (variant, event,
    controller, scenario, seed), its reason in words with its numbers; none: one line."""
    text = fall_text(fall_frame(), not_caught_frame(), alarms_frame(), False, CAUGHT_DROP_M, WINDOW_S)
    section = text[text.index("### Falls not caught"):text.index("### False alarms")]
    assert [line for line in section.splitlines() if line.startswith("| healthy |")] == [
        "| healthy | trip | adaptive | steady | 2 | detected, but the pelvis had dropped 0.250 m at the lock "
        "(> 0.22 m) |",
        "| healthy | push | pid | steady | 1 | not detected: the arm never locked; the human fell 0.90 s "
        "after the onset |",
        "| healthy | push | adaptive | steady | 1 | no event: the human fell at 2.10 s, before the onset at "
        "3.00 s |",
        "| healthy | push | adaptive | steady | 2 | no event: the arm locked at 2.50 s, before the onset at "
        "3.00 s |",
        "| healthy | push | adaptive | steady | 3 | the simulation went unstable |",
        "| healthy | push | adaptive | walk_10m | 0 | not detected: the arm locked 2.20 s after the onset "
        "(window 1.50 s) |",
    ]
    caught = fall_text(fall_frame(), not_caught_frame().iloc[0:0], alarms_frame(), False, CAUGHT_DROP_M,
                       WINDOW_S)
    section = caught[caught.index("### Falls not caught"):caught.index("### False alarms")]
    assert section.splitlines()[2] == ("Every event that fell walking free was caught: 9 of 9 rollouts "
                                       "with a controller.")
    assert "| Why not caught |" not in section


def test_cohort_figures_are_listed_only_with_robot_rows():
    """`figure_names` (what the index shows) has cohort.png with cohort_controllers rows and
    fall_intervention.png with a robot condition in fall_intervention."""
    def frame(*cols: str) -> pd.DataFrame:
        return pd.DataFrame(columns=["subject", *cols])

    data = {"kinematics": frame("side", "source", "human_mode"), "events": frame("event", "scenario"),
            "spm_tests": frame("test_id", "test"), "spm_curves": pd.DataFrame(columns=["test_id"]),
            "tracking": frame(), "harness": frame(), "tuning": frame(),
            "cohort_controllers": controllers_frame(), "fall": fall_frame()}
    assert figure_names("s1", data)[-2:] == ["cohort", "fall_intervention"]
    data["fall"] = fall_frame().query("condition == 'free'")
    data["cohort_controllers"] = controllers_frame().iloc[0:0]
    assert not {"cohort", "fall_intervention"} & set(figure_names("s1", data))


# -- published values and params ----------------------------------------------------------------------


def test_clinical_ranges_load_with_a_source_for_every_entry():
    ranges = load_clinical_ranges()
    assert len(ranges) >= 5
    for name, r in ranges.items():
        assert r.source.strip() and r.meaning.strip(), name
        assert r.measure in CLINICAL_MEASURES
    assert ranges["stroke_limited_community_ambulator"].speed_mps == (0.4, 0.8)
    assert ranges["stroke_household_ambulator"].value_text() == "< 0.4"
    assert ranges["stroke_community_ambulator"].value_text() == "> 0.8"
    assert "Stroke 1995;26(6):982-989" in ranges["stroke_community_ambulator"].source
    assert ranges["swing_time_symmetry"].swing_ratio == (1.0, 1.06)


@pytest.mark.parametrize(("entry", "problem"), [
    ("a: {speed_mps: [0.4, 0.8], meaning: m}", "a.source: Field required"),
    ("a: {speed_mps: [0.4, 0.8], swing_ratio: 1.1, meaning: m, source: s}", "needs exactly one measure"),
    ("a: {speed_mps: [0.8, 0.4], meaning: m, source: s}", "low <= high"),
    ("a: {speed_kmh: [1, 2], meaning: m, source: s}", "a.speed_kmh: Extra inputs are not permitted"),
    ("a: [", "not YAML"),
])
def test_clinical_ranges_name_the_file_and_the_problem(tmp_path, entry, problem):
    path = tmp_path / "ranges.yaml"
    path.write_text(entry)
    with pytest.raises(PaperError, match="ranges.yaml") as err:
        load_clinical_ranges(path)
    assert problem in str(err.value)


def test_caught_threshold_and_variants_follow_params(params):
    """The report's caught threshold comes from params (robot.fall.drop_m + the margin); its variant
    order names every variant params declares."""
    rule = params.fall_intervention.rule(params.robot.fall.drop_m)
    assert report_params(params).caught_drop_m == pytest.approx(rule.caught_drop_m)
    assert report_params(params).caught_drop_m == pytest.approx(params.robot.fall.drop_m
                                                                + params.fall_intervention.caught_margin_m)
    assert set(VARIANT_ORDER) == {"healthy", *params.cohort.variants}
    assert list(params.fall_intervention.variants) == [v for v in VARIANT_ORDER if v in
                                                       params.fall_intervention.variants]


def test_values_stay_finite_in_the_heatmap_cells():
    """Every written cell is a number or a dash, never "nan"."""
    fig = cohort_heatmap(controllers_frame().assign(force_rms_n=np.nan), "t")
    assert all(t != "nan" for ax in fig.axes for t in texts(ax))
    assert texts(panel_axes(fig)[2]) == ["–"] * 6
