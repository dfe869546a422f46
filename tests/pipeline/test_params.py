"""params.yaml's schema (pipeline/params.py): library defaults equal the file, errors name the file
and the key path, the CLI turns them into one line; the paths of pipeline/paths.py."""

from __future__ import annotations

import dataclasses
import pickle
import re
from pathlib import Path

import pytest
import yaml

from pipeline.cli import main
from pipeline.commands.tune_controllers import write_gains
from pipeline.params import PARAMS_FILE, Params, ParamsError, load_params, parse_params
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
from sim.robot.controllers.specs import read_tuned, write_tuned
from sim.rollout.loop import RolloutParams

# Not a tunable default: the tuning walks are a list of specs (the per-walk optional keys default to
# WalkParams' fields, which the schema uses as is).
NOT_COMPARED = {"TuningParams.walks"}


def doc() -> dict:
    return yaml.safe_load(PARAMS_FILE.read_text())


def write(tmp_path: Path, document: dict, name: str = "params.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


def built(params: Params) -> dict[str, object]:
    """Every dataclass the sections turn into, by name."""
    retarget = params.retarget.build()
    return {
        "IngestParams": params.ingest.build(),
        "MetricsParams": params.metrics.build(),
        "StoreParams": params.store.build(),
        "ReportParams": params.report.build(),
        "RetargetParams": retarget.ik,
        "ReferenceParams": retarget.reference,
        "RobotParams": params.robot.build(),
        "TuningParams": params.robot.tuning.build(),
        "ReplayParams": params.rollout.replay.build(),
        "HumanParams": params.human.build(),
        "TrainParams": params.train.build(),
        "EvalParams": params.evaluate_policy.build(),
        "PolicyChecks": params.evaluate_policy.checks.build(),
        "ScenarioChecks": params.evaluate_policy.scenario_checks.build(),
        "ProfileParams": params.scenarios.profile.build(),
        "QualityParams": params.quality.build(),
        "RolloutParams": RolloutParams(robot=params.robot.build(),
                                       max_physics_dt_s=params.rollout.max_physics_dt_s,
                                       start_offset_m=params.rollout.start_offset_m),
    }


def drift(value, default, where: str) -> list[str]:
    """Fields of `value` (from params.yaml) that differ from `default`, recursing into dataclasses."""
    out = []
    for f in dataclasses.fields(value):
        name = f"{where}.{f.name}"
        a, b = getattr(value, f.name), getattr(default, f.name)
        if name in NOT_COMPARED:
            continue
        if dataclasses.is_dataclass(a) and type(a) is type(b):
            out += drift(a, b, name)
        elif a != b:
            out.append(f"{name}: default {b!r}, params.yaml {a!r}")
    return out


def test_library_defaults_equal_params_yaml(params):
    problems = []
    for name, value in built(params).items():
        cls = type(value)
        required = {f.name: getattr(value, f.name) for f in dataclasses.fields(cls)
                    if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
        problems += drift(value, cls(**required), name)  # the defaults, required fields as in params
    assert not problems, "library defaults drifted from params.yaml:\n" + "\n".join(problems)


def test_every_key_of_params_yaml_is_read_and_kept(params):
    assert params.document() == doc()
    assert params.path == PARAMS_FILE
    assert pickle.loads(pickle.dumps(params)) == params  # goes to process-pool workers


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d["robot"]["base"].update(mass_kg="heavy"),
     r"params\.yaml: robot\.base\.mass_kg: Input should be a valid number.*\(got 'heavy'\)$"),
    (lambda d: d["ingest"]["bouts"].pop("smooth_hz"),
     r"params\.yaml: ingest\.bouts: missing key 'smooth_hz'$"),
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
        load_params(write(tmp_path, document))


def test_several_errors_are_listed_in_one_message():
    document = doc()
    document["ingest"]["filter"]["order"] = 4.5
    document["report"].pop("dpi")
    with pytest.raises(ParamsError) as err:
        parse_params(document)
    assert err.value.problem == ("ingest.filter.order: Input should be a valid integer, got a number with a "
                                 "fractional part (got 4.5); report: missing key 'dpi'")


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
    bad = write(tmp_path, document, "bad.yaml")
    assert main(["--params", str(bad), "ingest", "camargo", "--out-root", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {bad}: robot.base.mass_kg: Input should be a "
                                                   "valid number")
    assert not (tmp_path / "camargo").exists()


def test_tuned_gains_file_is_read_on_top_of_params(tmp_path, params):
    tuned = tmp_path / "controllers.yaml"
    gains = {"kp_x": 1.5, "ki_x": 2.0, "kd_x": 0.25, "kp_y": 3.0, "ki_y": 0.5, "kd_y": 0.75}
    write_tuned(tuned, {"pid": gains, "adaptive": read_tuned(TUNED_GAINS)["adaptive"]}, "a test's")
    assert read_tuned(tuned)["pid"] == gains
    loaded = load_params(PARAMS_FILE, tuned)
    assert loaded.robot.controller_specs()["pid"] == {"class": "pid", "gains": {**gains, "i_max": 0.1}}
    assert loaded.robot.controller_specs()["adaptive"] == params.robot.controller_specs()["adaptive"]
    assert loaded.document() == params.document()  # params.yaml's own text is untouched by tuning
    # a gain is set in one place: in params.yaml too it would be silently overridden, so it is an error
    document = doc()
    document["robot"]["controllers"]["pid"]["gains"]["kp_x"] = 99.0
    with pytest.raises(ParamsError, match=r"robot\.controllers\.pid\.gains\.kp_x: also set in the "
                                          r"tuned-gains file \(1\.5 there, 99\.0 here\)"):
        parse_params(document, PARAMS_FILE, tuned)


def test_tune_controllers_writes_results_not_params(tmp_path, params):
    """`tune-controllers` writes the searched gains to the tuned-gains file; params.yaml is not edited."""
    path = tmp_path / "controllers.yaml"
    path.write_text(TUNED_GAINS.read_text())
    before = PARAMS_FILE.read_text()
    gains = {"kp_x": 1.5, "ki_x": 2.0, "kd_x": 0.25, "kp_y": 3.0, "ki_y": 0.5, "kd_y": 0.75}
    write_gains(path, {"controllers": {"pid": {"class": "pid", "gains": {**gains, "i_max": 0.1}}}}, params)
    assert read_tuned(path) == {**read_tuned(TUNED_GAINS), "pid": gains}  # searched gains only, adaptive kept
    assert path.read_text().startswith("# The follow-me controllers' tuned gains")
    assert load_params(PARAMS_FILE, path).robot.controller_specs()["pid"]["gains"] == {**gains, "i_max": 0.1}
    assert PARAMS_FILE.read_text() == before


@pytest.mark.parametrize(("tuned", "path", "message"), [
    ({"pid": {"kp_x": 1.0}}, "params",
     r"robot\.controllers\.pid\.gains\.ki_x: missing: required gain of PID \(forward speed per integrated "
     r"forward deflection, 1/s\^2\), given neither"),
    ({"lqr": {"k": 1.0}}, "tuned", r"lqr: no controller 'lqr' in robot\.controllers"),
    ({"pid": {"kp_x": "fast"}}, "tuned", r"pid\.kp_x: expected a number \(got 'fast'\)"),
])
def test_tuned_gains_file_errors_name_the_file_and_key(tmp_path, tuned, path, message):
    file = tmp_path / "controllers.yaml"
    file.write_text(yaml.safe_dump({**read_tuned(TUNED_GAINS), **tuned}))
    where = {"params": PARAMS_FILE, "tuned": file}[path]
    with pytest.raises(ParamsError, match=rf"^{re.escape(str(where))}: {message}"):
        load_params(PARAMS_FILE, file)


def test_paths_build_the_documented_layout(params):
    assert PROCESSED_ROOT == REPO_ROOT / "data" / "processed" and REPORTS_ROOT == REPO_ROOT / "reports"
    assert human_xml(PROCESSED_ROOT, "s") == model_dir(PROCESSED_ROOT, "s") / "human.xml"
    assert reference_npz("root", "s") == Path("root/s/model/reference.npz")
    assert [f("root", "s") for f in (real_dir, sim_dir, sim_policy_dir, report_dir)] == [
        Path("root/s/real"), Path("root/s/sim"), Path("root/s/sim_policy"), Path("root/s")]
    assert params.store.build().path == repo_path(params.store.path) == STORE_FILE
    assert repo_path("/abs/x.duckdb") == Path("/abs/x.duckdb")
    assert repo_relative(REPORTS_ROOT / "s" / "a.png") == "reports/s/a.png"
    assert repo_relative(Path("/elsewhere/a.png")) == "/elsewhere/a.png"


def test_retarget_params_reject_unknown_keys():
    section = load_params().retarget.build()
    assert section.reference.conditions == ("free",) and section.ik.iterations >= 1
    doc = yaml.safe_load(PARAMS_FILE.read_text())
    retarget = doc["retarget"]
    with pytest.raises(ParamsError, match=r"params\.yaml: retarget: unknown key 'cycle_sample'$"):
        parse_params({**doc, "retarget": {**retarget, "cycle_sample": 10}})
    with pytest.raises(ParamsError, match=r"params\.yaml: retarget\.ik: unknown key 'iteration'$"):
        parse_params({**doc, "retarget": {**retarget, "ik": {**retarget["ik"], "iteration": 3}}})
    with pytest.raises(ParamsError, match=r"params\.yaml: missing section 'retarget'$"):
        parse_params({k: v for k, v in doc.items() if k != "retarget"})


def test_a_scenario_segment_of_two_kinds_is_refused_with_its_key_path(tmp_path):
    doc = yaml.safe_load(PARAMS_FILE.read_text())
    doc["scenarios"]["commands"]["walk_10m"][1] = {"walk_m": 10.0, "turn_deg": 90.0}
    with pytest.raises(ParamsError, match=r"scenarios\.commands\.walk_10m\[1\]: .*exactly one of"):
        parse_params(doc, tmp_path / "params.yaml")
    del doc["scenarios"]["commands"]["turn_90"]
    doc["scenarios"]["commands"]["walk_10m"][1] = {"walk_m": 10.0}
    with pytest.raises(ParamsError, match="missing scenario.*turn_90"):
        parse_params(doc, tmp_path / "params.yaml")


def test_a_variant_may_have_its_own_budget_and_one_longer_swing(tmp_path, params):
    """`cohort.variants.<v>.fine_tune_steps` overrides the cohort's budget for that variant only;
    `swing_time_ratio` names one side and a ratio of at least 1."""
    document = doc()
    variants = document["cohort"]["variants"]
    variants["weak"] = {"torque_scale": {"all": 0.6}, "fine_tune_steps": 123}
    variants["slow"] = {"speed_mps": 0.6}
    loaded = load_params(write(tmp_path, document))
    assert loaded.fine_tune_steps("weak") == 123
    assert loaded.fine_tune_steps("slow") == document["cohort"]["fine_tune_steps"]
    assert loaded.variant("weak").torque_factor("hip_l") == pytest.approx(0.6)
    side, ratio = params.variant("hemiparetic_left").swing_time_ratio
    assert side == "left" and ratio > 1.0
    variants["slow"] = {"action_noise": 0.08, "train_action_noise": 0.15}
    noisy = load_params(write(tmp_path, document))
    assert noisy.variant("slow").action_noise == 0.08
    assert noisy.train_params("slow").env.variant.training_noise == 0.15
    variants["slow"] = {"swing_time_ratio": {"left": 0.8}}
    with pytest.raises(ParamsError, match=r"cohort\.variants\.slow\.swing_time_ratio\.left"):
        load_params(write(tmp_path, document))
    variants["slow"] = {"swing_time_ratio": {"left": 1.2, "right": 1.2}}
    with pytest.raises(ParamsError, match=r"cohort\.variants\.slow\.swing_time_ratio: .*at most 1 item"):
        load_params(write(tmp_path, document))
