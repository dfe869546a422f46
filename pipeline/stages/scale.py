"""Stage `scale <subject>`: the subject's static trial -> the scaled 27-DoF human.

Outputs, written all-or-nothing: `<root>/<subject>/model/human.xml` (MJCF from `MjSpec.to_xml`,
keyframe `static` = the static pose), `<root>/<subject>/model/model.json` (segment lengths and
masses, joint-centre sources, static hinge angles, checks: DoF counts, total mass, standing height,
thigh and shank lengths; `markers_left_out`: the static markers on no body of the model, hence not
fitted by the retarget, with their distance to the nearest bone and why; a DVC metrics file) and
`reports/<subject>/model.png` (the model in the static pose with the real static markers; `render` in
model.json says how it was drawn).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from ingest.manifest import Manifest
from ingest.static import StaticCheckParams, read_static_trial
from ingest.subject import STATIC_NONE, load_subject
from pipeline.params import Params
from pipeline.paths import PROCESSED_ROOT, REPORTS_ROOT, human_xml, model_dir, report_dir
from pipeline.stages.outputs import json_text, replacing
from sim.body.human import build_human, model_checks
from sim.body.human_params import HumanParams
from sim.body.render import render_model_png
from sim.body.scaling import ScaledBody, knee_valgus_deg, scale_subject
from sim.errors import SimulationError


def _rounded(d: dict, digits: int = 4) -> dict:
    return {k: round(float(v), digits) for k, v in d.items()}


def markers_left_out(body: ScaledBody, limit_m: float) -> dict[str, dict]:
    """model.json's `markers_left_out`: each static marker on no body, its distance to the nearest
    bone and why (the quality gate can name them)."""
    return {name: {"distance_m": round(d, 4),
                   "reason": f"no landmark role or segments entry, {d * 100:.1f} cm from the nearest bone "
                             f"(human.marker_bone_distance_max_m: {limit_m} m): not fitted by the retarget"}
            for name, d in sorted(body.markers_left_out.items())}


def run_scale(subject_id: str, params: Params, root: Path = PROCESSED_ROOT,
              reports_root: Path = REPORTS_ROOT) -> Path:
    """Scale, build, check and render `subject_id`'s human; returns the model folder."""
    subject = load_subject(subject_id)
    p = params.section("human", HumanParams)
    check = params.section("ingest.static", StaticCheckParams)
    static = read_static_trial(subject, Manifest.load(), check=check, widths_per_height=p.widths_per_height)
    body = scale_subject(subject, static, p)
    synthesised = subject.static is not None and subject.static.markers == STATIC_NONE
    spec = build_human(body, p)
    model = spec.compile()
    xml = spec.to_xml()
    checks = model_checks(model, body)
    folder = model_dir(root, subject_id)
    png = report_dir(reports_root, subject_id) / "model.png"
    summary = {
        "subject": subject_id, "height_m": body.height_m, "mass_kg": body.mass_kg,
        "anthropometry": body.anthropometry,
        "segment_lengths_m": _rounded(body.segment_lengths_m),
        "segment_masses_kg": _rounded(body.segment_masses_kg),
        "joint_centre_sources": body.length_sources,
        "static_hinge_angles_deg": _rounded({k: np.degrees(v) for k, v in body.static_angles_rad.items()}, 2),
        "neutral": body.neutral,  # joint zeros (human.neutral after any fallback)
        "static_ik_deg": _rounded(body.static_ik_deg, 2),  # the static IK the zeros are calibrated to
        # not measured where the standing pose is synthesised from the walks: its legs stand straight
        "static_knee_valgus_deg": None if synthesised else {
            s: round(knee_valgus_deg(body.joint_centres, s), 2) for s in ("l", "r")},
        "markers": len(body.marker_bodies),
        "markers_left_out": markers_left_out(body, p.marker_bone_distance_max_m),
        "checks": checks,
    }
    xml_out, json_out, png_out = human_xml(root, subject_id), folder / "model.json", png
    with replacing(xml_out, json_out, png_out) as (xml_tmp, json_tmp, png_tmp):
        xml_tmp.write_text(xml)
        if mujoco.MjModel.from_xml_path(str(xml_tmp)).nv != model.nv:
            raise SimulationError(xml_out, "saved MJCF does not reload to the same model")
        summary["render"] = render_model_png(
            xml_tmp, model.key_qpos[0], body.markers, body.height_m, png_tmp,
            title=f"{subject_id}: {body.height_m:.2f} m, {body.mass_kg:.1f} kg, static pose")
        json_tmp.write_text(json_text(summary))
    return folder
