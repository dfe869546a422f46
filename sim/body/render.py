"""Pictures of the scaled human in its static pose with the real static markers.

MuJoCo offscreen rendering needs an OpenGL backend chosen before `mujoco` is imported
(`MUJOCO_GL`), so each backend is tried in a child process (`python -m sim.body.render`): EGL first,
then OSMesa (Debian `libosmesa6`, installed by `make render-deps` when neither is present). When
neither works the picture is a matplotlib 3-D stick figure of the same model and markers, so a PNG
is always produced; `render_model_png` returns which method drew it.

Picture: front and side views; model geoms in skin colour, virtual markers (model sites) blue,
the real static markers red, both in the static frame.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

BACKENDS = ("egl", "osmesa")
REAL_RGBA = (0.9, 0.1, 0.1, 0.5)  # translucent: the model markers show through
VIEWS = (("front", 180.0), ("side", 90.0))  # free-camera azimuth (deg): looking at the face / left side


def _offscreen(xml_path: Path, qpos: np.ndarray, markers: np.ndarray, height_m: float,
               size_px: tuple[int, int]) -> list[np.ndarray]:
    """Images (one per view) rendered with the backend of this process's MUJOCO_GL."""
    import mujoco

    from sim.body.human import MARKER_SITE_GROUP

    model = mujoco.MjModel.from_xml_path(str(xml_path))
    model.site_size[:, 0] = np.maximum(model.site_size[:, 0], 0.012)  # visible at this resolution
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    h, w = size_px
    model.vis.global_.offwidth, model.vis.global_.offheight = max(w, 640), max(h, 480)
    renderer = mujoco.Renderer(model, h, w)
    opt = mujoco.MjvOption()
    opt.sitegroup[MARKER_SITE_GROUP] = 1
    images = []
    for _, azimuth in VIEWS:
        cam = mujoco.MjvCamera()
        cam.lookat[:] = [0.0, 0.0, height_m / 2]
        cam.distance, cam.azimuth, cam.elevation = 1.6 * height_m, azimuth, -5.0
        renderer.update_scene(data, camera=cam, scene_option=opt)
        scene = renderer.scene
        for p in markers:
            if scene.ngeom >= scene.maxgeom:
                break
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE,
                                np.array([0.018, 0, 0]), np.asarray(p, float), np.eye(3).ravel(),
                                np.array(REAL_RGBA, np.float32))
            scene.ngeom += 1
        images.append(renderer.render().copy())
    renderer.close()
    return images


def _stick_figure(xml_path: Path, qpos: np.ndarray, markers: np.ndarray, ax_front, ax_side) -> None:
    """matplotlib fallback: bones (parent body -> child body origins), virtual and real markers."""
    import mujoco

    from sim.body.markers import marker_positions

    model = mujoco.MjModel.from_xml_path(str(xml_path))
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    virtual = np.array(list(marker_positions(model, data).values()))
    for ax, (_, azimuth) in zip((ax_front, ax_side), VIEWS, strict=True):
        for b in range(2, model.nbody):
            a, c = data.xpos[model.body_parentid[b]], data.xpos[b]
            ax.plot(*np.column_stack([a, c]), color="peru", lw=3)
        for g in range(model.ngeom):
            if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
                ax.scatter(*data.geom_xpos[g], color="dimgray", s=20)
        ax.scatter(*markers.T, color="red", s=40, alpha=0.4, label="real static markers")
        ax.scatter(*virtual.T, color="royalblue", s=8, label="model markers")
        ax.view_init(elev=5, azim=azimuth - 180)
        ax.set_box_aspect((1, 1, 2))
        ax.set_xlim(-0.5, 0.5)
        ax.set_ylim(-0.5, 0.5)
        ax.set_zlim(0.0, 2.0)


def render_model_png(xml_path: str | Path, qpos: np.ndarray, markers: dict[str, np.ndarray],
                     height_m: float, out_png: str | Path, title: str = "",
                     size_px: tuple[int, int] = (720, 450), timeout_s: float = 120.0) -> str:
    """Write `out_png`; returns the method used: 'mujoco-egl', 'mujoco-osmesa' or 'matplotlib'."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xml_path, out_png = Path(xml_path), Path(out_png)
    real = np.array([v for v in markers.values()], float).reshape(-1, 3)
    images, method = None, "matplotlib"
    with tempfile.TemporaryDirectory() as tmp:
        job = Path(tmp) / "job.npz"
        np.savez(job, qpos=qpos, markers=real, height_m=height_m, size_px=np.array(size_px))
        for backend in BACKENDS:
            out = Path(tmp) / f"{backend}.npy"
            env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
            try:
                cmd = [sys.executable, "-m", "sim.body.render", str(xml_path), str(job), str(out)]
                run = subprocess.run(cmd, env=env, capture_output=True, timeout=timeout_s,
                                     cwd=Path(__file__).resolve().parents[2])
            except subprocess.TimeoutExpired:
                continue
            if run.returncode == 0 and out.is_file():
                images, method = np.load(out), f"mujoco-{backend}"
                break
    out_png.parent.mkdir(parents=True, exist_ok=True)
    if images is not None:
        fig, axes = plt.subplots(1, len(images), figsize=(4 * len(images), 6.5))
        for ax, img, (view, _) in zip(axes, images, VIEWS, strict=True):
            ax.imshow(img)
            ax.set_title(view)
            ax.axis("off")
    else:
        fig = plt.figure(figsize=(8, 6.5))
        axes = [fig.add_subplot(1, 2, k + 1, projection="3d") for k in range(2)]
        _stick_figure(xml_path, qpos, real, *axes)
        axes[0].legend(loc="upper left", fontsize=7)
    fig.suptitle(f"{title}\nskin: model geoms; red: real static markers, blue: model markers (they "
                 "coincide in the static pose) "
                 f"[{method}]", fontsize=9)
    fig.tight_layout()
    fig.savefig(out_png, dpi=100, format="png")
    plt.close(fig)
    return method


def main(argv: list[str]) -> int:
    """Child process: `python -m sim.body.render MODEL.xml JOB.npz OUT.npy` (MUJOCO_GL set by the parent)."""
    xml_path, job, out = (Path(a) for a in argv)
    d = np.load(job)
    images = _offscreen(xml_path, d["qpos"], d["markers"], float(d["height_m"]), tuple(d["size_px"]))
    np.save(out, np.stack(images))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
