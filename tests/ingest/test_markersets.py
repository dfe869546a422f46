"""Marker sets by name or path, derived roles and the automatic pick by coverage (ingest/markersets.py),
on the real recordings of ../shared/data."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ingest.canonical import load_trial
from ingest.errors import SubjectError
from ingest.manifest import Manifest, Source, sha256_of
from ingest.markersets import load_markerset, load_segments, pick_markerset, shipped_markersets, with_derived
from ingest.process import landmarks, process_trial
from ingest.readers import read_markers
from ingest.readers.trc import write_trc
from ingest.subject import load_subject

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data"
PSIS = ("L_PSIS", "R_PSIS")

# Dataset file -> the shipped set it should get (/work/shared/data/README.md).
EXPECTED = {
    "camargo2021_levelground/MarkerData/levelground_ccw_fast_01_01.trc": "camargo",
    "opencap_labval_subject4/MarkerData/walking1.trc": "opencap_labval",
    "opencap_labval_subject4/MarkerData/static1.trc": "opencap_labval",
    "pose2sim_demo_markerless/S00_P00_T00_StaticTrial_0-12.trc": "pose2sim_halpe26",
    "moissenet_GaitEventsAlgorithms_norm/NormSubjects/walkNorm_NP1014a05.c3d": "plugin_gait",
    "lenhart2015_opensim-jam/models/lenhart2015/motion_data/overground_17.trc": "lenhart2015",
    "kgc6_DM_jam-resources/models/knee_tka/grand_challenge/DM/experimental_data/motion_analysis/"
    "DM_ngait_og1_new.trc": "kgc6",
    "falisse2019_3dpredictsim/OpenSimModel/subject2/TRC/gait_14.trc": "falisse2019",
}


@pytest.fixture(scope="module")
def camargo():
    subject = load_subject("camargo")
    return subject, subject.trials[0], Manifest.load()


def _write_set(path: Path, doc: dict) -> Path:
    path.write_text(yaml.safe_dump(doc))
    return path


def test_every_shipped_set_loads():
    for name in shipped_markersets():
        assert len(load_markerset(name)) == 12


def test_set_by_path_processes_a_trial(tmp_path, camargo, ingest_params):
    subject, spec, manifest = camargo
    doc = yaml.safe_load((ROOT / "data/markersets/camargo.yaml").read_text())
    path = _write_set(tmp_path / "mylab.yaml", doc)
    by_path = load_markerset(str(path))
    assert by_path == load_markerset("camargo") == subject.markerset
    relative = load_markerset("data/markersets/camargo.yaml")  # relative to the repo root
    assert relative == by_path
    processed = process_trial(load_trial(dataclasses.replace(subject, markerset=by_path), spec, manifest),
                              by_path, ingest_params)
    assert processed.strides["kept"].sum() >= 4


def test_unknown_set_names_it_and_lists_the_shipped(tmp_path):
    with pytest.raises(SubjectError, match=r"unknown marker set 'nolab'.*camargo.*plugin_gait"):
        load_markerset("nolab")
    with pytest.raises(SubjectError, match=r"nothere\.yaml.*camargo"):
        load_markerset(str(tmp_path / "nothere.yaml"))


def test_set_missing_roles_is_refused_listing_them(tmp_path):
    doc = yaml.safe_load((ROOT / "data/markersets/plugin_gait.yaml").read_text())
    del doc["psis_left"], doc["knee_right"]
    path = _write_set(tmp_path / "partial.yaml", doc)
    with pytest.raises(SubjectError, match=r"partial\.yaml.*missing roles knee_right, psis_left"):
        load_markerset(str(path))
    with pytest.raises(SubjectError, match="unknown derivation 'magic'"):
        load_markerset(str(_write_set(tmp_path / "bad.yaml", {**doc, "psis_left": {"derive": "magic"},
                                                                   "knee_right": "RKNE"})))


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_auto_pick_on_the_real_files(key):
    path = DATA / key
    if not path.is_file():
        pytest.skip(f"{path} not in the data mirror")
    assert pick_markerset(read_markers(path).names, path) == EXPECTED[key]


def test_no_fitting_set_lists_the_missing_roles(tmp_path):
    """falisse2019's walks (unnamed foot markers foot_l1..10) against the shipped sets without its own."""
    path = DATA / "falisse2019_3dpredictsim/OpenSimModel/subject2/TRC/gait_14.trc"
    if not path.is_file():
        pytest.skip(f"{path} not in the data mirror")
    sets = ROOT / "data/markersets"
    for name in shipped_markersets():
        if name != "falisse2019":
            (tmp_path / f"{name}.yaml").write_text((sets / f"{name}.yaml").read_text())
    with pytest.raises(SubjectError, match=r"gait_14\.trc.*no shipped marker set fits.*plugin_gait lacks "
                       r"heel_left \(LHEE\), heel_right \(RHEE\), toe_left \(LTOE\)"):
        pick_markerset(read_markers(path).names, path, tmp_path)


def test_sacral_psis_derived_back_on_camargo(tmp_path, camargo, ingest_params):
    """SACR = the midpoint of Camargo's real PSIS, PSIS dropped, PSIS derived back from SACR."""
    subject, spec, manifest = camargo
    table = read_markers(manifest.resolve(spec.markers))
    index = {n: j for j, n in enumerate(table.names)}
    sacr = table.xyz_m[:, [index[n] for n in PSIS]].mean(axis=1, keepdims=True)
    keep = [j for n, j in index.items() if n not in PSIS]
    names = [table.names[j] for j in keep] + ["SACR"]
    trc = write_trc(tmp_path / "sacral.trc", table.time_s, names,
                    np.concatenate([table.xyz_m[:, keep], sacr], axis=1), unit="m")
    doc = yaml.safe_load((ROOT / "data/markersets/camargo.yaml").read_text())
    sacral = {"derive": "sacral", "marker": "SACR"}
    doc.update(psis_left=sacral, psis_right=sacral)
    derived_set = load_markerset(str(_write_set(tmp_path / "camargo_sacr.yaml", doc)))
    mirror = Manifest({"sacral.trc": Source("sacral.trc", trc.as_uri(), sha256_of(trc))}, tmp_path, tmp_path)
    derived_spec = dataclasses.replace(spec, markers="sacral.trc", angles=None, grf=None)
    derived = load_trial(dataclasses.replace(subject, markerset=derived_set), derived_spec, mirror)
    real = load_trial(subject, dataclasses.replace(spec, angles=None, grf=None), manifest)
    lm_real, lm_derived = landmarks(real, subject.markerset), landmarks(derived, derived_set)
    for role in ("asis_left", "asis_right", "psis_left", "psis_right"):
        error = np.linalg.norm(lm_real[role] - lm_derived[role], axis=1)
        assert np.nanmax(error) < 0.03, role
    processed = process_trial(derived, derived_set, ingest_params)
    assert processed.strides["kept"].sum() >= 4


def test_keypoint_pelvis_gives_back_the_hip_centres(tmp_path):
    """ASIS/PSIS derived from the keypoints' hip centres give those centres back by Harrington."""
    from ingest.kinematics import hip_joint_centres
    from ingest.markersets import with_derived

    path = DATA / "pose2sim_demo_markerless/S00_P00_T00_StaticTrial_0-12.trc"
    if not path.is_file():
        pytest.skip(f"{path} not in the data mirror")
    table = read_markers(path)
    xyz = table.xyz_m[..., [0, 2, 1]] * [1, -1, 1]  # Y up -> Z up
    markers = with_derived({n: xyz[:, j] for j, n in enumerate(table.names)}, ms := load_markerset(
        "pose2sim_halpe26"))
    lm = {r: markers[n] for r, n in ms.items()}
    hjc = hip_joint_centres(lm["asis_left"], lm["asis_right"], lm["psis_left"], lm["psis_right"])
    assert np.allclose(hjc["left"], markers["LHip"], atol=1e-6)
    assert np.allclose(hjc["right"], markers["RHip"], atol=1e-6)
    assert np.all(lm["asis_left"][:, 2] > lm["psis_left"][:, 2] - 0.1)


def test_cluster_derivation_places_a_point_fixed_in_the_cluster(tmp_path):
    """`derive: cluster` (kgc6_clusters.yaml): the offset in the frame origin A, x toward B, z normal to
    ABC, carried through a rotation of the cluster; an input written as (0, 0, 0) is a gap."""
    doc = yaml.safe_load((ROOT / "data/markersets/kgc6.yaml").read_text())
    doc["knee_left"] = {"derive": "cluster", "markers": ["A", "B", "C"], "offset_m": [0.1, 0.02, -0.03]}
    ms = load_markerset(str(_write_set(tmp_path / "cl.yaml", doc)))
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    pts = {"A": np.array([[1.0, 2.0, 0.5]] * 2), "B": np.array([[1.0, 2.0, 0.2]] * 2),
           "C": np.array([[1.1, 2.0, 0.4]] * 2)}
    pts = {k: np.vstack([v[:1], (turn @ v[1])[None]]) for k, v in pts.items()}
    pts["A"] = np.vstack([pts["A"], [[0.0, 0.0, 0.0]]])
    pts["B"], pts["C"] = (np.vstack([v, v[-1:]]) for v in (pts["B"], pts["C"]))
    knee = with_derived(pts, ms)[ms["knee_left"]]
    # frame of the first sample: x down (-z), z = x cross (C - A) = -y, y = z cross x = +x (lab)
    assert np.allclose(knee[0], [1.0 + 0.02, 2.0 + 0.03, 0.5 - 0.1])
    assert np.allclose(knee[1], turn @ knee[0])
    assert np.isnan(knee[2]).all()
    with pytest.raises(SubjectError, match=r"knee_left: derive cluster gives a role from"):
        doc["knee_left"] = {"derive": "cluster", "markers": ["A", "B"], "offset_m": [0.1, 0.0, 0.0]}
        load_markerset(str(_write_set(tmp_path / "bad.yaml", doc)))


def test_segments_give_markers_without_a_role_their_body(tmp_path):
    doc = yaml.safe_load((ROOT / "data" / "markersets" / "opencap_labval.yaml").read_text())
    doc["segments"] = {"thigh_l": ["L_thigh1", "L_thigh2"], "shank_r": ["r_sh2"]}
    path = tmp_path / "with_segments.yaml"
    path.write_text(yaml.safe_dump(doc))
    assert load_markerset(path) == load_markerset("opencap_labval")  # roles unchanged
    assert load_segments(path) == {"L_thigh1": "thigh_l", "L_thigh2": "thigh_l", "r_sh2": "shank_r"}
    assert load_segments("opencap_labval") == {}


@pytest.mark.parametrize("segments, problem", [
    (["L_thigh1"], "segments: maps a body of the model to its markers"),
    ({"thigh_l": "L_thigh1"}, "segments: maps a body of the model to its markers"),
    ({"thigh_l": ["L_thigh1"], "shank_l": ["L_thigh1"]}, "segments: marker L_thigh1 is given two bodies "
     "(shank_l, thigh_l)"),  # safe_dump sorts the bodies
])
def test_bad_segments_are_refused_naming_the_file(tmp_path, segments, problem):
    doc = yaml.safe_load((ROOT / "data" / "markersets" / "opencap_labval.yaml").read_text())
    doc["segments"] = segments
    path = tmp_path / "bad_segments.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(SubjectError, match=problem.replace("(", r"\(").replace(")", r"\)")) as err:
        load_markerset(path)
    assert str(path) in str(err.value)
