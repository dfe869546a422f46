"""`python -m pipeline <command>`."""

import os
import sys

# One BLAS / OpenMP thread per process, set before numpy loads: the numerical work is many small
# matrices, parallelism comes from process pools (simulate, evaluate-policy) and torch's own
# threads (train --threads); idle BLAS threads spin and would take a core from a pool worker
# (measured: 8 rollouts in a 2-process pool 0.59 s with the default threads, 0.29 s with one).
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# `render` draws offscreen: MuJoCo and PyOpenGL pick their GL backend when they are first imported,
# so it is chosen here (EGL unless the caller set one), and only for that command.
if sys.argv[1:2] == ["render"]:
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

from pipeline.cli import main  # noqa: E402

raise SystemExit(main())
