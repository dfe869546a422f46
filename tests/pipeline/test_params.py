"""params.yaml (pipeline/params.py): each section validated by its library class (`SECTIONS`), errors
name the file and the key path, the CLI turns them into one line; the paths of pipeline/paths.py."""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import pytest
import yaml

from ingest.process import IngestParams
from pipeline.cli import main
from pipeline.commands.tune_controllers import write_gains
from pipeline.params import (
    HEALTHY as PARAMS_HEALTHY,
)
from pipeline.params import (
    PARAMS_FILE,
    SECTIONS,
    ParamsError,
    check_params,
    checked,
    load_params,
    parse_params,
    section_class,
)
from pipeline.paths import (
    PROCESSED_ROOT,
    REPO_ROOT,
    REPORTS_ROOT,
    STORE_FILE,
    TUNED_GAINS,
    human_xml,
    model_dir,
    real_dir,
    reference_npz,
    repo_path,
    repo_relative,
    report_dir,
    sim_dir,
    sim_policy_dir,
)
from pipeline.runs.setup import controller_specs, fine_tune_steps, train_params, variant
from pipeline.runs.tuned_gains import read_tuned, write_tuned
from sim.body.variant import HEALTHY, CohortSection
from sim.motion.reference import ReferenceParams
from sim.rollout.scenarios import ScenariosSection


def doc() -> dict:
    return yaml.safe_load(PARAMS_FILE.read_text())


def write(tmp_path: Path, document: dict, name: str = "params.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


def test_every_section_has_its_class_and_the_file_names_them_all(params):
    assert list(SECTIONS) == list(doc())  # every section of the file is known, in the file's order
    for name in SECTIONS:
        assert params.section(name, section_class(name)) == getattr(params, name)
    assert isinstance(params.ingest, IngestParams) and isinstance(params.retarget, ReferenceParams)
    assert PARAMS_HEALTHY == HEALTHY  # the cross-section checks' name of a subject's own policy


def test_a_key_left_out_takes_the_library_default(tmp_path):
    document = doc()
    document["ingest"]["bouts"].pop("smooth_hz")
    del document["metrics"]["spm"]
    loaded = load_params(write(tmp_path, document))
    assert loaded.section("ingest", IngestParams).bouts.smooth_hz == IngestParams().bouts.smooth_hz
    assert loaded.section("ingest", IngestParams) == load_params().section("ingest", IngestParams)


def test_every_key_of_params_yaml_is_read_and_kept(params):
    assert params.document() == doc()
    assert params.path == PARAMS_FILE
    assert pickle.loads(pickle.dumps(params)) == params  # goes to process-pool workers


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d["robot"]["base"].update(mass_kg="heavy"),
     r"params\.yaml: robot\.base\.mass_kg: Input should be a valid number.*\(got 'heavy'\)$"),
    (lambda d: d["rollout"].pop("workers"),
     r"params\.yaml: rollout: missing key 'workers'$"),
    (lambda d: d["robot"]["harness"].update(stifness=[1.0] * 6),
     r"params\.yaml: robot\.harness: unknown key 'stifness'$"),
    (lambda d: d["robot"]["tuning"]["walks"][1].update(speed_mps=[1.2]),
     r"params\.yaml: robot\.tuning\.walks\[1\]\.speed_mps: Input should be a valid number$"),
    (lambda d: d["human"].update(contact_solref=[0.02]),
     r"params\.yaml: human\.contact_solref\[1\]: missing item$"),
    (lambda d: d["ingest"]["events"].update(method="magic"),
     r"params\.yaml: ingest\.events\.method: Input should be 'auto', 'force' or 'kinematic' "
     r"\(got 'magic'\)$"),
    (lambda d: d.pop("evaluate_policy"), r"params\.yaml: missing section 'evaluate_policy'$"),
    (lambda d: d.update(extra={"a": 1}), r"params\.yaml: unknown section 'extra'$"),
    (lambda d: d["rollout"].update(conditions=["free", "pdi"]),
     r"params\.yaml: rollout\.conditions: 'pdi' is neither free nor a controller in robot\.controllers$"),
    (lambda d: d["robot"]["tuning"]["initial"].update(lqr={"k": 1.0}),
     r"params\.yaml: robot\.tuning\.initial\.lqr: no controller 'lqr' in robot\.controllers$"),
    # issue 34 case 14: these passed the check and failed seconds later as raw tracebacks (KeyError: 'kp_x')
    (lambda d: d["ingest"]["filter"].update(cutoff_hz=-6.0),
     r"params\.yaml: ingest\.filter\.cutoff_hz: Input should be greater than 0 \(got -6\.0\)$"),
    (lambda d: d["robot"]["controllers"]["pid"]["gains"].update(kp_xx=1.0),
     r"params\.yaml: robot\.controllers\.pid\.gains\.kp_xx: unknown gain of PID \(it takes kp_x, ki_x, kd_x, "
     r"kp_y, ki_y, kd_y, i_max\)$"),
    (lambda d: d["robot"]["controllers"]["pid"]["gains"].update(i_max=-0.1),
     r"params\.yaml: robot\.controllers\.pid\.gains\.i_max: -0\.1 outside \[0, inf\] \(integrator clamp "),
    (lambda d: d["robot"]["controllers"]["adaptive"]["gains"].update(comb_compensaton=1.0),
     r"params\.yaml: robot\.controllers\.adaptive\.gains\.comb_compensaton: unknown gain of Adaptive "),
    (lambda d: d["robot"]["tuning"]["initial"]["pid"].update(i_max=0.1),
     r"params\.yaml: robot\.tuning\.initial\.pid\.i_max: not a searched gain of PID \(searched: kp_x, "),
    (lambda d: d["tune"]["search"]["adaptive"].update(log_q_e=[0.0, 1.0]),
     r"params\.yaml: tune\.search\.adaptive\.log_q_e: not a searched gain of Adaptive "),
    (lambda d: d["tune"]["search"]["pid"].update(kp_x=[-1.0, 20.0]),
     r"params\.yaml: tune\.search\.pid\.kp_x: \[-1\.0, 20\.0\] outside the declared bounds \[0, inf\]$"),
    # these passed the check before: a count of seeds below 1, a physics step of 0, a negative offset
    (lambda d: d["rollout"].update(n_seeds=-3),
     r"params\.yaml: rollout\.n_seeds: Input should be greater than or equal to 1 \(got -3\)$"),
    (lambda d: d["evaluate_policy"].update(n_seeds=0),
     r"params\.yaml: evaluate_policy\.n_seeds: Input should be greater than or equal to 1 \(got 0\)$"),
    (lambda d: d["rollout"].update(max_physics_dt_s=0.0),
     r"params\.yaml: rollout\.max_physics_dt_s: Input should be greater than 0 \(got 0\.0\)$"),
    (lambda d: d["rollout"].update(start_offset_m=-0.03),
     r"params\.yaml: rollout\.start_offset_m: Input should be greater than or equal to 0 \(got -0\.03\)$"),
])
def test_errors_name_the_file_and_the_key_path(tmp_path, edit, message):
    document = doc()
    edit(document)
    with pytest.raises(ParamsError, match=message):
        check_params(write(tmp_path, document))


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d["ingest"]["bouts"].update(smooth_hz="slow"),
     r"params\.yaml: ingest\.bouts\.smooth_hz: Input should be a valid number.*\(got 'slow'\)$"),
    (lambda d: d["ingest"]["static"].update(max_foot_sprad_m=0.04),
     r"params\.yaml: ingest\.static: unknown key 'max_foot_sprad_m'$"),
    (lambda d: d["ingest"]["filter"].update(cutoff_hz=-6.0),
     r"params\.yaml: ingest\.filter\.cutoff_hz: Input should be greater than 0 \(got -6\.0\)$"),
])
def test_a_stage_loading_its_section_gets_the_same_errors(tmp_path, edit, message):
    """The ingest stage validates only `ingest`; its errors are the whole file's."""
    document = doc()
    edit(document)
    params = load_params(write(tmp_path, document))
    with pytest.raises(ParamsError, match=message):
        params.section("ingest", IngestParams)


def test_values_other_sections_set_are_refused_in_the_file(tmp_path):
    document = doc()
    document["report"]["caught_drop_m"] = 0.3
    document["train"]["env"]["profile"] = {"start_s": 1.0}
    with pytest.raises(ParamsError, match=r"report\.caught_drop_m: set from robot\.fall\.drop_m \+ "
                                          r"fall_intervention\.caught_margin_m, not in the file; "
                                          r"train\.env\.profile: set from scenarios\.profile"):
        load_params(write(tmp_path, document))


def test_several_errors_are_listed_in_one_message():
    document = doc()
    document["ingest"]["filter"]["order"] = 4.5
    document["rollout"].pop("workers")
    with pytest.raises(ParamsError) as err:
        checked(parse_params(document))
    assert err.value.problem == ("ingest.filter.order: Input should be a valid integer, got a number with a "
                                 "fractional part (got 4.5); rollout: missing key 'workers'")


@pytest.mark.parametrize(("text", "message"), [
    (None, r"none\.yaml: cannot read params file"),
    ("a: [", r"none\.yaml: not valid YAML"),
    ("- camargo\n", r"none\.yaml: expected a mapping of sections"),
])
def test_unreadable_files_name_the_file(tmp_path, text, message):
    path = tmp_path / "none.yaml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(ParamsError, match=message):
        load_params(path)


def test_cli_bad_params_is_one_line_error(tmp_path, capsys):
    document = doc()
    document["robot"]["base"]["mass_kg"] = "heavy"
    document["ingest"]["filter"]["cutoff_hz"] = "high"
    bad = write(tmp_path, document, "bad.yaml")
    assert main(["--params", str(bad), "ingest", "camargo", "--out-root", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {bad}: ingest.filter.cutoff_hz: Input should be "
                                                   "a valid number")
    assert not (tmp_path / "camargo").exists()
    assert main(["--params", str(bad), "check-params"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"error: {bad}: ingest.filter.cutoff_hz: " in err
    assert "; robot.base.mass_kg: Input should be a valid number" in err
    assert main(["check-params"]) == 0


def test_tuned_gains_file_is_read_on_top_of_params(tmp_path, params):
    tuned = tmp_path / "controllers.yaml"
    gains = {"kp_x": 1.5, "ki_x": 2.0, "kd_x": 0.25, "kp_y": 3.0, "ki_y": 0.5, "kd_y": 0.75}
    write_tuned(tuned, {"pid": gains, "adaptive": read_tuned(TUNED_GAINS)["adaptive"]}, "a test's")
    assert read_tuned(tuned)["pid"] == gains
    loaded = load_params(PARAMS_FILE, tuned)
    assert loaded.tuned_file == tuned and params.tuned_file == TUNED_GAINS
    assert controller_specs(loaded)["pid"] == {"class": "pid", "gains": {**gains, "i_max": 0.1}}
    assert controller_specs(loaded)["adaptive"] == controller_specs(params)["adaptive"]
    assert loaded.document() == params.document()  # params.yaml's own text is untouched by tuning
    assert check_params(PARAMS_FILE, tuned).tuned_file == tuned
    # a gain is set in one place: in params.yaml too it would be silently overridden, so it is an error
    document = doc()
    document["robot"]["controllers"]["pid"]["gains"]["kp_x"] = 99.0
    with pytest.raises(ParamsError, match=r"robot\.controllers\.pid\.gains\.kp_x: also set in the "
                                          r"tuned-gains file \(1\.5 there, 99\.0 here\)"):
        controller_specs(parse_params(document, PARAMS_FILE, tuned))


def test_tune_controllers_writes_results_not_params(tmp_path, params):
    """`tune-controllers` writes the searched gains to the tuned-gains file; params.yaml is not edited."""
    path = tmp_path / "controllers.yaml"
    path.write_text(TUNED_GAINS.read_text())
    before = PARAMS_FILE.read_text()
    gains = {"kp_x": 1.5, "ki_x": 2.0, "kd_x": 0.25, "kp_y": 3.0, "ki_y": 0.5, "kd_y": 0.75}
    write_gains(path, {"controllers": {"pid": {"class": "pid", "gains": {**gains, "i_max": 0.1}}}}, params)
    assert read_tuned(path) == {**read_tuned(TUNED_GAINS), "pid": gains}  # searched gains only, adaptive kept
    assert path.read_text().startswith("# The follow-me controllers' tuned gains")
    assert controller_specs(load_params(PARAMS_FILE, path))["pid"]["gains"] == {**gains, "i_max": 0.1}
    assert PARAMS_FILE.read_text() == before


@pytest.mark.parametrize(("tuned", "path", "message"), [
    ({"pid": {"kp_x": 1.0}}, "params",
     r"robot\.controllers\.pid\.gains\.ki_x: missing: required gain of PID \(forward speed per integrated "
     r"forward deflection, 1/s\^2\), given neither"),
    ({"lqr": {"k": 1.0}}, "tuned", r"lqr: no controller 'lqr' in robot\.controllers"),
    ({"pid": {"kp_x": "fast"}}, "tuned", r"pid\.kp_x: expected a number \(got 'fast'\)"),
])
def test_tuned_gains_file_errors_name_the_file_and_key(tmp_path, tuned, path, message):
    """A stage reading the controllers (`controller_specs`) and `check-params` report them alike."""
    file = tmp_path / "controllers.yaml"
    file.write_text(yaml.safe_dump({**read_tuned(TUNED_GAINS), **tuned}))
    where = {"params": PARAMS_FILE, "tuned": file}[path]
    with pytest.raises(ParamsError, match=rf"^{re.escape(str(where))}: {message}"):
        controller_specs(load_params(PARAMS_FILE, file))
    with pytest.raises(ParamsError, match=rf"^{re.escape(str(where))}: {message}"):
        check_params(PARAMS_FILE, file)


def test_a_bad_tuned_gains_file_names_itself(tmp_path):
    file = tmp_path / "controllers.yaml"
    file.write_text("- pid\n")
    with pytest.raises(ParamsError, match=rf"^{re.escape(str(file))}: expected controller name -> "):
        check_params(PARAMS_FILE, file)


def test_paths_build_the_documented_layout(params):
    assert PROCESSED_ROOT == REPO_ROOT / "data" / "processed" and REPORTS_ROOT == REPO_ROOT / "reports"
    assert human_xml(PROCESSED_ROOT, "s") == model_dir(PROCESSED_ROOT, "s") / "human.xml"
    assert reference_npz("root", "s") == Path("root/s/model/reference.npz")
    assert [f("root", "s") for f in (real_dir, sim_dir, sim_policy_dir, report_dir)] == [
        Path("root/s/real"), Path("root/s/sim"), Path("root/s/sim_policy"), Path("root/s")]
    assert params.store.path == repo_path(doc()["store"]["path"]) == STORE_FILE
    assert repo_path("/abs/x.duckdb") == Path("/abs/x.duckdb")
    assert repo_relative(REPORTS_ROOT / "s" / "a.png") == "reports/s/a.png"
    assert repo_relative(Path("/elsewhere/a.png")) == "/elsewhere/a.png"


def test_retarget_params_reject_unknown_keys():
    section = load_params().section("retarget", ReferenceParams)
    assert section.conditions == ("free",) and section.ik.iterations >= 1
    doc = yaml.safe_load(PARAMS_FILE.read_text())
    retarget = doc["retarget"]

    def load(section: dict) -> ReferenceParams:
        return parse_params({**doc, "retarget": section}).section("retarget", ReferenceParams)

    with pytest.raises(ParamsError, match=r"params\.yaml: retarget: unknown key 'cycle_sample'$"):
        load({**retarget, "cycle_sample": 10})
    with pytest.raises(ParamsError, match=r"params\.yaml: retarget\.ik: unknown key 'iteration'$"):
        load({**retarget, "ik": {**retarget["ik"], "iteration": 3}})
    with pytest.raises(ParamsError, match=r"params\.yaml: missing section 'retarget'$"):
        parse_params({k: v for k, v in doc.items() if k != "retarget"})


def test_a_scenario_segment_of_two_kinds_is_refused_with_its_key_path(tmp_path):
    doc = yaml.safe_load(PARAMS_FILE.read_text())
    doc["scenarios"]["commands"]["walk_10m"][1] = {"walk_m": 10.0, "turn_deg": 90.0}
    with pytest.raises(ParamsError, match=r"scenarios\.commands\.walk_10m\[1\]: .*exactly one of"):
        parse_params(doc, tmp_path / "params.yaml").section("scenarios", ScenariosSection)
    del doc["scenarios"]["commands"]["turn_90"]
    doc["scenarios"]["commands"]["walk_10m"][1] = {"walk_m": 10.0}
    with pytest.raises(ParamsError, match="missing scenario.*turn_90"):
        parse_params(doc, tmp_path / "params.yaml").section("scenarios", ScenariosSection)


def test_a_variant_may_have_its_own_budget_and_one_longer_swing(tmp_path, params):
    """`cohort.variants.<v>.fine_tune_steps` overrides the cohort's budget for that variant only;
    `swing_time_ratio` names one side and a ratio of at least 1."""
    document = doc()
    variants = document["cohort"]["variants"]
    variants["weak"] = {"torque_scale": {"all": 0.6}, "fine_tune_steps": 123}
    variants["slow"] = {"speed_mps": 0.6}
    loaded = load_params(write(tmp_path, document))
    assert fine_tune_steps(loaded, "weak") == 123
    assert fine_tune_steps(loaded, "slow") == document["cohort"]["fine_tune_steps"]
    assert variant(loaded, "weak").torque_factor("hip_l") == pytest.approx(0.6)
    side, ratio = params.variant("hemiparetic_left").swing_time_ratio
    assert side == "left" and ratio > 1.0
    variants["slow"] = {"action_noise": 0.08, "train_action_noise": 0.15}
    noisy = load_params(write(tmp_path, document))
    assert variant(noisy, "slow").action_noise == 0.08
    assert train_params(noisy, "slow").env.variant.training_noise == 0.15
    with pytest.raises(ParamsError, match=r"cohort\.variants: no variant 'stroke' \(healthy, weak"):
        variant(noisy, "stroke")
    variants["slow"] = {"swing_time_ratio": {"left": 0.8}}
    with pytest.raises(ParamsError, match=r"cohort\.variants\.slow\.swing_time_ratio\.left"):
        load_params(write(tmp_path, document)).section("cohort", CohortSection)
    variants["slow"] = {"swing_time_ratio": {"left": 1.2, "right": 1.2}}
    with pytest.raises(ParamsError, match=r"cohort\.variants\.slow\.swing_time_ratio: .*at most 1 item"):
        load_params(write(tmp_path, document)).section("cohort", CohortSection)
