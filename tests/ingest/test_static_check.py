"""The static (scaling) trial must be quiet standing (ingest/static.py): real statics and camargo's
standing window pass, walking and hopping given as static are refused naming the file and the failed
check, and `static: auto` finds the standing before camargo's walk."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ingest.errors import IngestError, SubjectError
from ingest.manifest import Manifest
from ingest.markersets import load_markerset
from ingest.readers.trc import read_trc, write_trc
from ingest.static import (
    StaticCheckParams,
    check_static,
    find_standing_window,
    read_static_trial,
    static_markers,
)
from ingest.subject import StaticSpec, load_subject

OC_WALK = "opencap_labval_subject4/MarkerData/walking1.trc"


@pytest.fixture(scope="module")
def manifest() -> Manifest:
    return Manifest.load()


def test_defaults_equal_params_yaml(params):
    assert params.ingest.static == StaticCheckParams()


def test_camargo_declared_window_and_opencap_static_pass(manifest):
    camargo, opencap = load_subject("camargo"), load_subject("opencap4")
    window = check_static(manifest.resolve(camargo.static.markers), camargo, camargo.static.window_s)
    lo, hi = camargo.static.window_s
    assert lo <= window.t0_s < window.t1_s <= hi and window.duration_s >= 1.0
    assert window.pelvis_speed_mps < 0.05
    whole = check_static(manifest.resolve(opencap.static.markers), opencap, None)
    assert whole.duration_s > 4.5  # 5.2 s of standing, minus the speed span at the ends


def test_walking_trial_given_as_static_is_refused(manifest):
    opencap = load_subject("opencap4")
    path = manifest.resolve(OC_WALK)
    with pytest.raises(IngestError) as info:
        check_static(path, opencap, None)
    message = str(info.value)
    assert str(path) in message and "not a static (quiet standing) trial" in message
    assert "pelvis moving: speed" in message and "> 0.1 m/s" in message
    assert "feet not flat" in message and "knees not extended" in message


def test_static_window_over_the_walk_is_refused(manifest):
    camargo = load_subject("camargo")
    subject = dataclasses.replace(camargo, static=dataclasses.replace(camargo.static, window_s=(4.0, 12.0)))
    with pytest.raises(IngestError, match=r"no 0.5 s in 4.0-12.0 s passes the standing checks: pelvis"):
        read_static_trial(subject, manifest)


def test_too_short_standing_is_refused(manifest):
    """1.5-2.0 s of camargo: the side-step ends at ~1.8 s, leaving < 0.5 s of standing."""
    camargo = load_subject("camargo")
    with pytest.raises(IngestError, match="no 0.5 s in 1.5-2.0 s"):
        check_static(manifest.resolve(camargo.static.markers), camargo, (1.5, 2.0))


def test_hopping_static_is_refused(manifest, tmp_path):
    """opencap4's static with every marker bobbing 5 cm at 2 Hz (a hop in place): the pelvis moves."""
    opencap = load_subject("opencap4")
    table = read_trc(manifest.resolve(opencap.static.markers))
    xyz = table.xyz_m.copy()
    xyz[..., 1] += 0.05 * np.sin(2 * np.pi * 2.0 * table.time_s)[:, None]  # the file is Y up
    path = write_trc(tmp_path / "hop.trc", table.time_s, table.names, xyz, unit="m")
    with pytest.raises(IngestError, match=r"hop\.trc.*pelvis moving: speed 0\.[3-9]\d* m/s > 0.1 m/s"):
        check_static(path, opencap, None)
    assert check_static(write_trc(tmp_path / "still.trc", table.time_s, table.names, table.xyz_m, unit="m"),
                        opencap, None).duration_s > 4.5  # the same file unmodified passes


def test_auto_finds_the_standing_before_camargos_walk(manifest, tmp_path):
    camargo = load_subject("camargo")
    window = find_standing_window([manifest.resolve(t.markers) for t in camargo.trials], camargo)
    assert 1.5 <= window.t0_s and window.t1_s <= 3.5 and window.duration_s >= 1.0
    # `static: auto` in a subject file: the same window, and the chosen trial's IK for the joint zeros
    text = (Path(camargo.path).read_text().split("static:")[0] + "static: auto\ntrials:"
            + Path(camargo.path).read_text().split("trials:")[1])
    (tmp_path / "camargo.yaml").write_text(text)
    auto = load_subject("camargo", tmp_path)
    assert auto.static == StaticSpec("auto")
    static = read_static_trial(auto, manifest)
    assert static.source == str(manifest.resolve(camargo.trials[0].markers))
    assert static.angles_source == str(manifest.resolve(camargo.trials[0].angles))
    declared = read_static_trial(camargo, manifest)
    for name in ("L_Heel", "R_ASIS"):  # the same standing pose as the declared window, within 5 mm
        assert np.linalg.norm(static.markers[name] - declared.markers[name]) < 0.005


def test_auto_without_standing_names_the_subject(manifest):
    opencap = load_subject("opencap4")
    with pytest.raises(SubjectError, match="opencap4.yaml: static auto: no 0.5 s of quiet standing"):
        read_static_trial(dataclasses.replace(opencap, static=StaticSpec("auto")), manifest)


def test_a_sacral_marker_set_can_use_its_static_trial(tmp_path, manifest):
    """opencap4's static with its PSIS replaced by one sacral marker (their midpoint) and a marker set
    deriving the PSIS from it: the quiet-standing check runs on the derived PSIS (it used to fail with
    'markers missing for psis_left') and the static carries them, within 3 cm of the real ones."""
    opencap = load_subject("opencap4")
    path = manifest.resolve(opencap.static.markers)
    table = read_trc(path)
    psis = [opencap.markerset["psis_left"], opencap.markerset["psis_right"]]
    index = {n: j for j, n in enumerate(table.names)}
    keep = [j for n, j in index.items() if n not in psis]
    sacr = table.xyz_m[:, [index[n] for n in psis]].mean(axis=1, keepdims=True)
    trc = write_trc(tmp_path / "static_sacr.trc", table.time_s, [table.names[j] for j in keep] + ["SACR"],
                    np.concatenate([table.xyz_m[:, keep], sacr], axis=1), unit="m")
    sacral = {"derive": "sacral", "marker": "SACR"}
    doc = {**opencap.markerset, "psis_left": sacral, "psis_right": sacral}
    (tmp_path / "opencap_sacr.yaml").write_text(yaml.safe_dump(doc))
    subject = dataclasses.replace(opencap, markerset=load_markerset(str(tmp_path / "opencap_sacr.yaml")),
                                  static=StaticSpec(markers=str(trc)))
    window = check_static(trc, subject, None)
    assert window.duration_s > 4.5  # as with its real PSIS
    static = static_markers(trc, subject)
    real = static_markers(path, opencap)
    for role in ("psis_left", "psis_right"):
        error = np.linalg.norm(static[subject.markerset[role]] - real[opencap.markerset[role]])
        assert error < 0.03, (role, error)
