"""The scaled human on the real subjects: DoF, mass, height, segment lengths against joint centres
computed here from the raw static markers, virtual markers, hinge signs, standing under a joint PD
for 5 s with the body weight on both feet, and a retargeted walk processed by ingest."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from ingest.canonical import load_trial, up_to_z
from ingest.errors import IngestError, SubjectError
from ingest.kinematics import hip_joint_centres
from ingest.manifest import Manifest
from ingest.process import landmarks, process_trial
from ingest.readers import read_markers
from ingest.static import read_static_trial, scaling_roles
from ingest.subject import load_subject
from sim.body.human import (
    FOOT_BIT,
    actuator_dofs,
    build_human,
    load_human_model,
    pose_hold_ctrl,
    pose_hold_gains,
    standing_height,
)
from sim.body.human_params import BALL_JOINTS, HINGE_JOINTS
from sim.body.markers import marker_positions, marker_sites, trial_from_qpos
from sim.body.scaling import cervical_joint_centre, scale_subject
from sim.errors import ScalingError, SimulationError
from sim.motion.retarget import retarget

SUBJECTS = {"camargo": (74.8, 1.80), "opencap4": (62.6, 1.68)}


@pytest.fixture(scope="module", params=sorted(SUBJECTS))
def human(request, hp, manifest, tmp_path_factory):
    """(subject, body, model) with the model reloaded from its saved MJCF, as the stage writes it."""
    subject = load_subject(request.param)
    static = read_static_trial(subject, manifest, widths_per_height=hp.widths_per_height)
    body = scale_subject(subject, static, hp)
    path = tmp_path_factory.mktemp(request.param) / "human.xml"
    path.write_text(build_human(body, hp).to_xml())
    return subject, body, load_human_model(path)


def static_data(model):
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("static").id)
    mujoco.mj_forward(model, data)
    return data


def test_dof_motor_and_body_layout(human, hp):
    subject, _, model = human
    assert (model.nv, model.nu, model.nq) == (27, 21, 33)
    assert model.joint("root").type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert model.body(model.joint("root").bodyid[0]).name == "pelvis"
    for j in BALL_JOINTS:
        assert model.joint(j).type[0] == mujoco.mjtJoint.mjJNT_BALL
        for ax in "xyz":
            assert model.actuator(f"{j}_{ax}").trnid[0] == model.joint(j).id
    for j in HINGE_JOINTS:
        assert model.joint(j).type[0] == mujoco.mjtJoint.mjJNT_HINGE
        assert model.actuator(j).trnid[0] == model.joint(j).id
    dofs, gears = actuator_dofs(model)
    assert sorted(dofs) == list(range(6, 27))  # one motor per actuated DoF
    assert np.all(model.actuator_ctrlrange == [-1, 1])
    limits = hp.torque_limit_nm_per_kg
    assert gears[list(dofs).index(model.joint("knee_l").dofadr[0])] == pytest.approx(
        limits["knee"] * subject.mass_kg, rel=1e-5)
    assert gears[list(dofs).index(model.joint("hip_r").dofadr[0] + 1)] == pytest.approx(
        limits["hip"] * subject.mass_kg, rel=1e-5)
    names = [model.body(i).name for i in range(model.nbody)]
    names += [model.joint(i).name for i in range(model.njnt)]
    assert not [n for n in names if n.startswith("mrba_")]
    assert model.opt.timestep == pytest.approx(0.002)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.geom("floor").type[0] == mujoco.mjtGeom.mjGEOM_PLANE


def test_total_mass_within_half_a_percent(human):
    subject, _, model = human
    assert SUBJECTS[subject.id][0] == subject.mass_kg
    assert abs(model.body_mass.sum() / subject.mass_kg - 1) < 0.005


def test_standing_height_within_two_percent(human):
    subject, _, model = human
    top = standing_height(model, static_data(model))
    head = static_data(model)
    head_top = head.geom_xpos[model.geom("head_geom").id, 2] + model.geom("head_geom").size[0]
    assert top == pytest.approx(head_top)
    assert abs(head_top / subject.height_m - 1) < 0.02
    upright = mujoco.MjData(model)
    mujoco.mj_kinematics(model, upright)
    assert abs(standing_height(model, upright) / subject.height_m - 1) < 0.02


def raw_joint_centres(subject, manifest, hp) -> dict[str, np.ndarray]:
    """Hip (Harrington 2007), knee and ankle centres straight from the static file, lab frame."""
    table = read_markers(manifest.resolve(subject.static.markers))
    xyz = up_to_z(table.xyz_m, subject.format.up_axis)
    if subject.static.window_s:
        keep = (table.time_s >= subject.static.window_s[0]) & (table.time_s <= subject.static.window_s[1])
        xyz = xyz[keep]
    med = {n: np.nanmedian(xyz[:, j], axis=0) for j, n in enumerate(table.names)}
    roles = scaling_roles(subject)
    m = {r: med[n] for r, n in roles.items() if n in med}
    hjc = hip_joint_centres(*(m[r][None] for r in ("asis_left", "asis_right", "psis_left", "psis_right")))
    out = {"hip_l": hjc["left"][0], "hip_r": hjc["right"][0]}
    left = (m["asis_left"] - m["asis_right"]) / np.linalg.norm(m["asis_left"] - m["asis_right"])
    for s, side, sign in (("l", "left", 1.0), ("r", "right", -1.0)):
        widths = {"knee": hp.knee_width_per_height, "ankle": hp.ankle_width_per_height}
        for joint, width in widths.items():
            if f"{joint}_medial_{side}" in m:
                out[f"{joint}_{s}"] = (m[f"{joint}_{side}"] + m[f"{joint}_medial_{side}"]) / 2
            else:
                out[f"{joint}_{s}"] = m[f"{joint}_{side}"] - sign * left * width * subject.height_m / 2
    return out


def test_thigh_and_shank_match_static_joint_centres(human, manifest, hp):
    subject, _, model = human
    jc = raw_joint_centres(subject, manifest, hp)
    data = static_data(model)
    for s in "lr":
        pos = {b: data.xpos[model.body(f"{b}_{s}").id] for b in ("thigh", "shank", "foot")}
        thigh, shank = np.linalg.norm(pos["shank"] - pos["thigh"]), np.linalg.norm(pos["foot"] - pos["shank"])
        assert abs(thigh - np.linalg.norm(jc[f"knee_{s}"] - jc[f"hip_{s}"])) < 0.015
        assert abs(shank - np.linalg.norm(jc[f"ankle_{s}"] - jc[f"knee_{s}"])) < 0.015
        assert 0.3 < thigh < 0.55 and 0.3 < shank < 0.55


def test_virtual_markers_sit_on_the_static_markers(human):
    subject, body, model = human
    names = set(read_markers(Manifest.load().resolve(subject.static.markers)).names)
    assert set(marker_sites(model)) == names == set(body.markers)
    got = marker_positions(model, static_data(model))
    worst = max(np.linalg.norm(got[n] - body.markers[n]) for n in names)
    assert worst < 1e-4  # the saved MJCF keeps about 6 significant digits
    bodies = {model.body(model.site_bodyid[i]).name for i in marker_sites(model).values()}
    assert {"pelvis", "thigh_l", "shank_r", "foot_l"} <= bodies
    for role, body_name in (("heel_left", "foot_l"), ("knee_right", "thigh_r"), ("asis_left", "pelvis")):
        assert model.body(model.site(subject.markerset[role]).bodyid[0]).name == body_name


def test_hinge_signs_are_canonical(human):
    """Knee + moves the ankle back, ankle + lifts the toes, elbow + brings the wrist forward."""
    _, _, model = human
    data = mujoco.MjData(model)

    def point(body, joint, angle):
        data.qpos[:] = model.qpos0
        data.qpos[model.joint(joint).qposadr[0]] = angle
        mujoco.mj_kinematics(model, data)
        return data.geom_xpos[model.geom(body).id].copy()

    for s in "lr":
        foot, toe, hand = f"foot_{s}_geom", f"foot_{s}_contact2", f"hand_{s}_geom"
        assert point(foot, f"knee_{s}", 0.5)[0] < point(foot, f"knee_{s}", 0.0)[0] - 0.1
        assert point(toe, f"ankle_{s}", 0.3)[2] > point(toe, f"ankle_{s}", 0.0)[2] + 0.02
        assert point(hand, f"elbow_{s}", 1.0)[0] > point(hand, f"elbow_{s}", 0.0)[0] + 0.1


def test_upright_at_qpos0_feet_flat_in_the_static_pose(human):
    """qpos0 is the joint-zero pose (with `neutral: static_ik` the zeros of the dataset's OpenSim
    model, so its feet need not be flat): upright, lowest foot contact on the floor. The static
    keyframe stands with both feet flat on the floor."""
    _, _, model = human
    data = mujoco.MjData(model)
    feet = [g for g in range(model.ngeom) if model.geom_contype[g] == FOOT_BIT and model.geom_bodyid[g] > 0]
    mujoco.mj_kinematics(model, data)
    bottoms = np.array([data.geom_xpos[g, 2] - model.geom_size[g, 0] for g in feet])
    assert bottoms.min() == pytest.approx(0.0, abs=1e-4)
    assert data.xpos[model.body("head").id, 2] > data.xpos[model.body("pelvis").id, 2] + 0.3
    data = static_data(model)
    bottoms = np.array([data.geom_xpos[g, 2] - model.geom_size[g, 0] for g in feet])
    assert np.abs(bottoms).max() < 0.01  # flat on the floor to within 1 cm


def test_static_pose_joint_angles_equal_the_static_ik(human, hp):
    """Static calibration (`human.neutral: static_ik`): the model's joint angles in its static pose
    are the dataset's own IK angles of that pose (opencap4: static1_ik.mot; camargo: the median of
    the walking IK over the quiet-standing window), read here independently of sim.body.scaling. The
    ankle hinge carries the calcaneus: ankle angle + (subtalar axis . talocrural axis) x subtalar
    angle to first order."""
    from ingest.canonical import canonical_angles
    from ingest.readers import read_mot
    from sim.motion.retarget import joint_angles

    subject, body, model = human
    assert body.neutral == "static_ik" and subject.static.angles is not None
    mot = read_mot(Manifest.load().resolve(subject.static.angles))
    assert mot.in_degrees is False
    real = canonical_angles(mot, subject.format, None)
    keep = np.ones(len(mot.time_s), bool)
    if subject.static.window_s:
        keep = (mot.time_s >= subject.static.window_s[0]) & (mot.time_s <= subject.static.window_s[1])
    sim = joint_angles(model, model.key("static").qpos[None])
    names = [f"{j}_{s}" for j in ("hip_flexion", "hip_adduction", "hip_rotation", "knee_flexion",
                                  "ankle_dorsiflexion") for s in ("left", "right")]
    names += ["pelvis_tilt", "pelvis_list"]
    for name in names:
        if name.startswith("ankle"):
            continue
        assert sim[name][0] == pytest.approx(np.median(real[name][keep]), abs=1e-3), name
    share = float(np.dot(hp.subtalar_axis, hp.talocrural_axis))
    assert share == pytest.approx(-0.31, abs=0.01)
    for s, side in (("l", "left"), ("r", "right")):
        subtalar = np.degrees(np.median(mot.table[f"subtalar_angle_{s}"].to_numpy(float)[keep]))  # radians
        expected = np.median(real[f"ankle_dorsiflexion_{side}"][keep]) + share * subtalar
        assert sim[f"ankle_dorsiflexion_{side}"][0] == pytest.approx(expected, abs=0.3), (side, subtalar)
    # the hinge axes stay anatomical: the knee axis is the static knee axis (markers / pelvis)
    data = static_data(model)
    for s in "lr":
        axis = data.xaxis[model.joint(f"knee_{s}").id]
        assert abs(axis[1]) > np.cos(np.radians(25)), (s, axis)  # medial-lateral, pointing left
        assert axis[1] > 0
def test_stands_five_seconds_on_both_feet_with_body_weight(human, hp):
    subject, _, model = human
    data = static_data(model)
    qref = data.qpos.copy()
    kp, kd = pose_hold_gains(model, hp)
    n = round(5.0 / model.opt.timestep)
    last = round(1.0 / model.opt.timestep)
    floor = model.geom("floor").id
    force = np.zeros(6)
    grf, feet_down = [], []
    for k in range(n):
        data.ctrl[:] = pose_hold_ctrl(model, data, qref, kp, kd)
        mujoco.mj_step(model, data)
        if k >= n - last:
            fz, sides = 0.0, set()
            for i in range(data.ncon):
                c = data.contact[i]
                if floor in (c.geom1, c.geom2):
                    mujoco.mj_contactForce(model, data, i, force)
                    fz += force[0]
                    other = c.geom2 if c.geom1 == floor else c.geom1
                    sides.add(model.body(model.geom_bodyid[other]).name)
            grf.append(fz)
            feet_down.append({"foot_l", "foot_r"} <= sides)
    weight = model.body_mass.sum() * -model.opt.gravity[2]
    assert abs(np.mean(grf) / weight - 1) < 0.02
    assert all(feet_down)
    torso_up = data.xmat[model.body("torso").id].reshape(3, 3)[:, 2]
    assert torso_up[2] > np.cos(np.radians(10))
    assert abs(data.qpos[2] - qref[2]) < 0.03


def test_simulated_trial_is_a_canonical_trial(human):
    subject, body, model = human
    qref = static_data(model).qpos.copy()
    qpos = np.repeat(qref[None], 50, axis=0)
    qpos[:, 0] += np.arange(50) * 0.012  # 1.2 m/s glide, 100 Hz
    trial = trial_from_qpos(model, qpos, 100.0, subject.id, "free", "glide")
    assert trial.source == "sim" and trial.n_frames == 50 and trial.rate_hz == 100.0
    assert set(trial.markers) == set(body.markers)
    lm = landmarks(trial, subject.markerset)
    heel = body.markers[subject.markerset["heel_left"]]
    assert lm is not None and np.allclose(lm["heel_left"][0], heel, atol=1e-4)
    assert np.allclose(np.diff(lm["asis_right"][:, 0]), 0.012)
    for name in ("hip_flexion_left", "knee_flexion_right", "ankle_dorsiflexion_left", "pelvis_tilt"):
        assert trial.angles[name].shape == (50,)
    assert trial.angles["knee_flexion_right"][0] == pytest.approx(
        np.degrees(body.static_angles_rad["knee_r"]), abs=1e-3)


def test_calcaneus_angle_is_the_twist_about_the_talocrural_axis():
    from sim.body.scaling import calcaneus_dorsiflexion_deg

    h, n = np.array([-0.105, -0.174, 0.979]), np.array([0.787, 0.605, -0.121])
    h, n = h / np.linalg.norm(h), n / np.linalg.norm(n)
    assert calcaneus_dorsiflexion_deg(12.0, 0.0, h, n) == pytest.approx(12.0, abs=1e-9)
    assert calcaneus_dorsiflexion_deg(12.0, -20.0, h, h) == pytest.approx(-8.0, abs=1e-9)
    assert calcaneus_dorsiflexion_deg(0.0, 10.0, h, n) == pytest.approx(10.0 * (h @ n), abs=0.1)
    side = np.cross(h, [0.0, 1.0, 0.0])
    assert abs(calcaneus_dorsiflexion_deg(5.0, 10.0, h, side / np.linalg.norm(side)) - 5.0) < 0.2


def test_errors_name_the_problem(hp, manifest, tmp_path):
    subject = load_subject("opencap4")
    with pytest.raises(SubjectError, match="no static trial"):
        read_static_trial(dataclasses.replace(subject, static=None), manifest)
    static = read_static_trial(subject, manifest)
    with pytest.raises(ScalingError, match="unknown anthropometry table 'nope'"):
        scale_subject(subject, static, dataclasses.replace(hp, anthropometry="nope"))
    missing = dataclasses.replace(subject, markerset={**subject.markerset, "heel_left": "NoSuchMarker"})
    with pytest.raises((IngestError, ScalingError), match=r"heel_left \(NoSuchMarker\)"):  # static check
        scale_subject(missing, read_static_trial(missing, manifest), hp)
    with pytest.raises(SimulationError, match="no human model here"):
        load_human_model(tmp_path / "absent.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><joint type='nonsense'/></body></worldbody></mujoco>")
    with pytest.raises(SimulationError, match="cannot compile"):
        load_human_model(bad)


def test_retargeted_walk_runs_through_ingest_like_the_recording(params, hp, manifest):
    """opencap4 walking1: real markers -> marker IK on the model -> virtual-marker Trial ->
    `process_trial`: the same kinematic gait events (within 40 ms) and stride length (3 cm)."""
    ip = params.ingest
    ip = dataclasses.replace(ip, events=dataclasses.replace(ip.events, method="kinematic"))
    subject = load_subject("opencap4")
    body = scale_subject(subject, read_static_trial(subject, manifest), hp)
    model = build_human(body, hp).compile()
    real = process_trial(load_trial(subject, subject.trials[0], manifest), subject.markerset, ip)
    fit = retarget(model, real.trial.markers, params.retarget.ik)
    trial = trial_from_qpos(model, fit.qpos, real.trial.rate_hz, subject.id, "free", "walking1",
                            t0_s=real.trial.time_s[0])
    sim = process_trial(trial, subject.markerset, ip)
    assert len(sim.events) == len(real.events) >= 4
    for (side, event), group in real.events.groupby(["side", "event"]):
        same = (sim.events["side"] == side) & (sim.events["event"] == event)
        got = sim.events.loc[same, "time_s"].to_numpy()
        for t in group["time_s"]:
            assert np.min(np.abs(got - t)) < 0.04
    kept_real = real.strides.loc[real.strides["kept"], "stride_length_m"].to_numpy()
    kept_sim = sim.strides.loc[sim.strides["kept"], "stride_length_m"].to_numpy()
    assert len(kept_real) == len(kept_sim) >= 1
    assert np.allclose(kept_sim, kept_real, atol=0.03)
    assert (sim.cycles["source"] == "sim").all()


def test_lower_body_marker_set_falls_back_to_ratios(hp, manifest):
    """opencap4 with only its main (lower-body landmark) marker set: knee and ankle centres from
    the lateral markers land within 2 cm of the lateral-medial midpoints (the width ratio is
    opencap4's own, so this checks the medial direction), trunk and arms from stature ratios, and
    the model keeps its layout, mass and height."""
    subject = load_subject("opencap4")
    static = read_static_trial(subject, manifest)
    full = scale_subject(subject, static, hp)
    lower = scale_subject(subject, dataclasses.replace(static, roles=dict(subject.markerset)), hp)
    for joint in ("knee_l", "knee_r", "ankle_l", "ankle_r"):
        assert full.length_sources[joint] == "markers"
        assert lower.length_sources[joint] == "lateral marker + width ratio"
        assert np.linalg.norm(full.joint_centres[joint] - lower.joint_centres[joint]) < 0.02
    assert lower.length_sources["neck"] == lower.length_sources["elbow_l"] == "height ratio"
    model = build_human(lower, hp).compile()
    assert (model.nv, model.nu) == (27, 21)
    assert model.body_mass.sum() == pytest.approx(subject.mass_kg, rel=1e-6)
    assert standing_height(model, static_data(model)) == pytest.approx(subject.height_m, abs=0.005)


def test_cervical_joint_centre_lies_inside_the_neck():
    """Reed et al.'s C7/T1 centre: in the sagittal plane of C7, the jugular notch and the point
    below, 55 % of the C7-notch distance from C7 on a line 8 deg above the C7->notch line."""
    c7, notch = np.array([-0.05, 0.01, 1.46]), np.array([0.09, 0.01, 1.40])
    below = np.array([0.03, 0.01, 0.9])
    cjc = cervical_joint_centre(c7, notch, below)
    d = np.linalg.norm(notch - c7)
    assert np.linalg.norm(cjc - c7) == pytest.approx(0.55 * d)
    assert cjc[1] == pytest.approx(0.01)
    along, to = (notch - c7) / d, (cjc - c7) / np.linalg.norm(cjc - c7)
    assert np.degrees(np.arccos(along @ to)) == pytest.approx(8.0)
    assert c7[0] < cjc[0] < notch[0]
    assert cjc[2] > c7[2] + (notch[2] - c7[2]) * (cjc[0] - c7[0]) / (notch[0] - c7[0])  # above the line


def test_neck_joint_sits_in_front_of_the_c7_marker(hp, manifest):
    """opencap4's static trial has C7 and sternum markers: the neck joint comes from both and lies
    4-9 cm in front of the C7 skin marker, so the trunk (mid-hip -> neck) stands within 5 deg of
    upright as the subject does; without the sternum markers it stands over the mid-hip at the C7
    marker's height."""
    subject = load_subject("opencap4")
    static = read_static_trial(subject, manifest)
    body = scale_subject(subject, static, hp)
    c7, neck, mid_hip = body.markers["C7"], body.joint_centres["neck"], body.joint_centres["mid_hip"]
    assert body.length_sources["neck"].startswith("Reed 1999")
    assert 0.04 < neck[0] - c7[0] < 0.09
    trunk = neck - mid_hip
    assert abs(np.degrees(np.arctan2(trunk[0], trunk[2]))) < 5.0
    roles = {k: v for k, v in static.roles.items() if not k.startswith("sternum")}
    no_sternum = scale_subject(subject, dataclasses.replace(static, roles=roles), hp)
    assert no_sternum.length_sources["neck"] == "C7 height over the mid-hip"
    assert np.allclose(no_sternum.joint_centres["neck"], [*mid_hip[:2], c7[2]])
