"""Which body each static marker rides on (sim/body/scaling.py `assign_markers`): by role, by the
marker set's `segments`, else the nearest bone within `human.marker_bone_distance_max_m`; farther
markers are left out of the model and listed (model.json `markers_left_out`: tests/pipeline/
test_markers_left_out.py), on real statics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from ingest.markersets import MARKERSETS_DIR, load_segments
from ingest.static import read_static_trial
from ingest.subject import load_subject
from sim.body.human import build_human
from sim.body.scaling import scale_subject
from sim.errors import ScalingError

THIGH_L = ("L_thigh1", "L_thigh2", "L_thigh3", "L_thigh4")


@pytest.fixture(scope="module")
def flexed(hp, manifest):
    """opencap4's static with the left elbow and wrist markers moved onto the left thigh (a forearm
    held along the thigh): its forearm bone runs through the thigh cluster."""
    subject = load_subject("opencap4")
    static = read_static_trial(subject, manifest, widths_per_height=hp.widths_per_height)
    m = dict(static.markers)
    left = m["L.ASIS"] - m["r.ASIS"]
    left[2] = 0.0
    left /= np.linalg.norm(left)
    centre = np.mean([m[n] for n in THIGH_L], axis=0)
    up = np.array([0.0, 0.0, 1.0])
    for joint, z in (("elbow", 0.12), ("wrist", -0.12)):
        m[f"L_{joint}_lat" if joint == "elbow" else "L_wrist_radius"] = centre + up * z + left * 0.03
        m[f"L_{joint}_med" if joint == "elbow" else "L_wrist_ulna"] = centre + up * z - left * 0.03
    return subject, dataclasses.replace(static, markers=m)


def test_without_segments_the_thigh_cluster_goes_to_the_forearm(flexed, hp):
    subject, static = flexed
    body = scale_subject(subject, static, hp)
    assert {body.marker_bodies[n] for n in THIGH_L} == {"forearm_l"}  # the nearest bone: issue 34 case 4


def test_segments_of_the_marker_set_put_the_thigh_cluster_on_the_thigh(flexed, hp, tmp_path):
    subject, static = flexed
    doc = yaml.safe_load((MARKERSETS_DIR / "opencap_labval.yaml").read_text())
    doc["segments"] = {"thigh_l": list(THIGH_L)}
    path = tmp_path / "opencap_flexed.yaml"
    path.write_text(yaml.safe_dump(doc))
    body = scale_subject(subject, dataclasses.replace(static, segments=load_segments(path)), hp)
    assert {body.marker_bodies[n] for n in THIGH_L} == {"thigh_l"}
    assert body.marker_bodies["L_elbow_lat"] == "upper_arm_l"  # roles first
    assert body.marker_bodies["L_wrist_radius"] == "forearm_l"
    assert body.markers_left_out == {}


def test_a_segment_body_the_model_lacks_is_refused(flexed, hp):
    subject, static = flexed
    with pytest.raises(ScalingError, match="segments: unknown bodies thigh_left"):
        scale_subject(subject, dataclasses.replace(static, segments={"L_thigh1": "thigh_left"}), hp)


def test_a_marker_far_from_every_bone_is_left_out_and_listed(flexed, hp):
    subject, static = flexed
    m = dict(static.markers)
    forward = m["L.ASIS"] + m["r.ASIS"] - m["L.PSIS"] - m["r.PSIS"]
    forward[2] = 0.0
    m["FAR"] = (m["L.ASIS"] + m["r.ASIS"]) / 2 + 0.5 * forward / np.linalg.norm(forward)
    body = scale_subject(subject, dataclasses.replace(static, markers=m), hp)
    assert "FAR" not in body.marker_bodies
    assert body.markers_left_out.keys() == {"FAR"}
    assert body.markers_left_out["FAR"] > hp.marker_bone_distance_max_m
    model = build_human(body, hp).compile()
    sites = {model.site(i).name for i in range(model.nsite)}
    assert "FAR" not in sites and set(THIGH_L) <= sites  # the retarget fits the model's sites only


@pytest.mark.parametrize("subject_id, arm", [
    ("falisse2019", {"LELB", "RELB", "LW1", "LW2", "RW1", "RW2", "LH", "RH", "rad_l2", "rad_r2"}),
    ("moissenet_np1014", {"RELB"}),
])
def test_bundled_arm_markers_once_on_the_pelvis_are_left_out(subject_id, arm, hp, manifest):
    subject = load_subject(subject_id)
    static = read_static_trial(subject, manifest, widths_per_height=hp.widths_per_height)
    body = scale_subject(subject, static, hp)
    assert body.markers_left_out.keys() == arm
    assert all(0.18 < d < 0.25 for d in body.markers_left_out.values())
    assert not arm & body.marker_bodies.keys()
