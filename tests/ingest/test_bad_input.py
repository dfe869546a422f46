"""A corpus of bad inputs built from the real recordings: each one gets a clear error naming the file
and the problem, or is handled correctly. Never a traceback from deep inside pandas, never a silently
wrong number.

Every case writes a modified copy of a real file into a temporary mirror with its own manifest, so
the real data and the repository's manifest are never touched.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ingest.canonical import load_trial
from ingest.errors import GaitloopError, IngestError, ManifestError, SubjectError
from ingest.manifest import Manifest, Source, sha256_of
from ingest.process import IngestParams, process_subject, process_trial
from ingest.readers import read_robot_log, read_trc
from ingest.robot_log import robot_table
from ingest.static import read_static_trial
from ingest.subject import FileFormat, StaticSpec, Subject, TrialSpec, load_subject

ROOT = Path(__file__).resolve().parents[2]
CAMARGO_TRC = "camargo2021_levelground/MarkerData/levelground_ccw_fast_01_01.trc"
CAMARGO_MOT = "camargo2021_levelground/IK/levelground_ccw_fast_01_01_ik.mot"
OPENCAP_WALK = "opencap_labval_subject4/MarkerData/walking1.trc"
UNREACHABLE_URL = "http://127.0.0.1:9/gaitloop-missing"  # refused at once: no network wait


@pytest.fixture(scope="module")
def real() -> Manifest:
    return Manifest.load()


@pytest.fixture(scope="module")
def camargo() -> Subject:
    return load_subject("camargo")


class Corpus:
    """A temporary mirror + manifest holding modified copies of real files."""

    def __init__(self, root: Path, real: Manifest) -> None:
        self.root, self.real = root, real
        self.sources: dict[str, Source] = {}

    def text(self, key: str) -> str:
        return self.real.resolve(key).read_text()

    def add(self, key: str, content: str | bytes) -> str:
        path = self.root / "mirror" / key
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content.encode() if isinstance(content, str) else content)
        self.sources[key] = Source(key, UNREACHABLE_URL, sha256_of(path))
        return key

    def manifest(self) -> Manifest:
        return Manifest(dict(self.sources), self.root / "mirror", self.root / "cache")

    def path(self, key: str) -> str:
        return str(self.root / "mirror" / key)


@pytest.fixture
def corpus(tmp_path, real) -> Corpus:
    return Corpus(tmp_path, real)


def _trc_edit(text: str, edit) -> str:
    """Apply `edit(row_values) -> row_values` to every data row of a TRC text (rows after line 5)."""
    lines = text.splitlines()
    out = lines[:5]
    for line in lines[5:]:
        if not line.strip():
            continue
        cells = line.split("\t")
        out.append("\t".join(edit(cells)))
    return "\n".join(out) + "\n"


def _marker_columns(text: str, marker: str) -> list[int]:
    names = text.splitlines()[3].split("\t")
    j = names.index(marker)
    return [j, j + 1, j + 2]


def _one_trial(subject: Subject, key: str, angles: str | None = None, **fmt) -> tuple[Subject, TrialSpec]:
    spec = TrialSpec(id="bad", condition="free", markers=key, angles=angles)
    subject = dataclasses.replace(subject, trials=(spec,),
                                  format=dataclasses.replace(subject.format, **fmt))
    return subject, spec


def _reference(camargo: Subject, real: Manifest, ingest_params: IngestParams):
    """The unmodified marker file through the same one-trial spec (no GRF, no .mot) as the cases."""
    subject, spec = _one_trial(camargo, CAMARGO_TRC)
    return process_trial(load_trial(subject, spec, real), subject.markerset, ingest_params)


def _raises(exc_type, *fragments: str):
    """pytest.raises whose message must contain every fragment."""

    class _Check:
        def __enter__(self):
            self.ctx = pytest.raises(exc_type)
            self.info = self.ctx.__enter__()
            return self.info

        def __exit__(self, *exc):
            suppressed = self.ctx.__exit__(*exc)
            message = str(self.info.value)
            for fragment in fragments:
                assert fragment in message, f"{fragment!r} not in {message!r}"
            assert "\n" not in message.strip()
            return suppressed

    return _Check()


# --- files that cannot be trusted ------------------------------------------------------------

def test_truncated_trc_names_file_and_truncation(corpus, camargo):
    text = corpus.text(CAMARGO_TRC)
    key = corpus.add(CAMARGO_TRC, text[: len(text) // 2])  # cut in the middle of a row
    subject, spec = _one_trial(camargo, key)
    with _raises(IngestError, corpus.path(key), "truncated"):
        load_trial(subject, spec, corpus.manifest())


def test_trc_missing_rows_at_the_end_is_truncated(corpus, camargo):
    lines = corpus.text(CAMARGO_TRC).splitlines()
    key = corpus.add(CAMARGO_TRC, "\n".join(lines[:-100]) + "\n")  # whole rows missing
    subject, spec = _one_trial(camargo, key)
    with _raises(IngestError, corpus.path(key), "header declares 3067 frames"):
        load_trial(subject, spec, corpus.manifest())


def test_empty_file(corpus, camargo):
    key = corpus.add(CAMARGO_TRC, "")
    subject, spec = _one_trial(camargo, key)
    with _raises(IngestError, corpus.path(key), "truncated"):
        load_trial(subject, spec, corpus.manifest())


def test_header_lies_about_units(corpus, camargo):
    """Metres in the data, `mm` in the header: the pelvis would be 1 mm above the feet."""
    lines = corpus.text(CAMARGO_TRC).splitlines()
    values = lines[2].split("\t")
    values[4] = "mm"
    lines[2] = "\t".join(values)
    key = corpus.add(CAMARGO_TRC, "\n".join(lines) + "\n")
    subject, spec = _one_trial(camargo, key)
    with _raises(IngestError, corpus.path(key), "units", "'mm'"):
        load_trial(subject, spec, corpus.manifest())


def test_millimetre_file_declared_as_such_gives_the_same_strides(corpus, camargo, real, ingest_params):
    """The same recording honestly in millimetres: converted, not rejected, same numbers."""
    text = corpus.text(CAMARGO_TRC)
    lines = text.splitlines()
    values = lines[2].split("\t")
    values[4] = "mm"
    lines[2] = "\t".join(values)

    def to_mm(cells):
        return cells[:2] + [f"{float(c) * 1000:.6f}" if c.strip() else c for c in cells[2:]]

    key = corpus.add(CAMARGO_TRC, _trc_edit("\n".join(lines) + "\n", to_mm))
    subject, spec = _one_trial(camargo, key)
    mm = process_trial(load_trial(subject, spec, corpus.manifest()), subject.markerset, ingest_params).strides
    ref = _reference(camargo, real, ingest_params).strides
    assert mm["kept"].tolist() == ref["kept"].tolist()
    np.testing.assert_allclose(mm["stride_length_m"], ref["stride_length_m"], atol=1e-6)


def test_y_up_file_declared_z_up(corpus, camargo):
    key = corpus.add(CAMARGO_TRC, corpus.text(CAMARGO_TRC))
    subject, spec = _one_trial(camargo, key, up_axis="z")
    with _raises(IngestError, corpus.path(key), "up_axis", "Z declared", "--up-axis"):
        load_trial(subject, spec, corpus.manifest())


def test_z_up_copy_declared_z_up_gives_the_same_strides(corpus, camargo, real, ingest_params):
    """The Y-up recording rotated to Z-up and declared so: the same strides come out."""

    def y_to_z(cells):
        out = cells[:2]
        for j in range(2, len(cells) - 2, 3):
            x, y, z = cells[j:j + 3]
            out += [x, f"{-float(z):.6f}" if z.strip() else z, y]
        return out

    key = corpus.add(CAMARGO_TRC, _trc_edit(corpus.text(CAMARGO_TRC), y_to_z))
    subject, spec = _one_trial(camargo, key, up_axis="z")
    zup = process_trial(load_trial(subject, spec, corpus.manifest()), subject.markerset,
                        ingest_params).strides
    ref = _reference(camargo, real, ingest_params).strides
    assert zup["kept"].tolist() == ref["kept"].tolist()
    np.testing.assert_allclose(zup["stride_length_m"], ref["stride_length_m"], atol=1e-6)


@pytest.mark.parametrize("layout", ["doubled tabs", "keys padded", "spaces", "names padded"])
def test_trc_header_aligned_with_repeated_tabs_or_spaces_reads_the_same(corpus, layout):
    """Exporters that align the header columns: keys, values and names padded with runs of tabs or
    spaces. Read by splitting on whitespace, the same table comes out (it used to say "unknown Units")."""
    text = corpus.text(CAMARGO_TRC)
    lines = text.splitlines()
    if layout == "doubled tabs":
        lines[1], lines[2] = lines[1].replace("\t", "\t\t"), lines[2].replace("\t", "\t\t")
    elif layout == "keys padded":
        lines[1] = lines[1].replace("\t", "\t\t\t")
    elif layout == "spaces":
        lines[1] = " ".join(f"{c:<20}" for c in lines[1].split("\t"))
        lines[2] = " ".join(f"{c:<20}" for c in lines[2].split("\t"))
    else:
        lines[3] = lines[3].replace("\t", "\t\t")
    key = corpus.add(CAMARGO_TRC, "\n".join(lines) + "\n")
    padded, ref = read_trc(corpus.manifest().resolve(key)), read_trc(corpus.real.resolve(CAMARGO_TRC))
    assert padded.names == ref.names and padded.rate_hz == ref.rate_hz and padded.declared_unit == "m"
    np.testing.assert_array_equal(padded.xyz_m, ref.xyz_m)


POSE2SIM_60HZ = "pose2sim_demo_markerless/S00_P00_T01_BalancingTrial_0-100.trc"


def test_trc_time_column_rounded_to_3_decimals_reads_at_the_header_rate(corpus, real):
    """Issue 34 case 6: 60 Hz with its Time column rounded to 0.001 s (steps 0.016 and 0.017 s) was read
    with a 0.017 s median step, 58.82 Hz, and made `simulate` 13x slower; the header's 60 Hz holds."""
    def round_time(cells):
        return [cells[0], f"{float(cells[1]):.3f}", *cells[2:]]

    key = corpus.add(POSE2SIM_60HZ, _trc_edit(corpus.text(POSE2SIM_60HZ), round_time))
    rounded, ref = read_trc(corpus.manifest().resolve(key)), read_trc(real.resolve(POSE2SIM_60HZ))
    assert rounded.rate_hz == ref.rate_hz == 60.0
    assert 1.0 / np.median(np.diff(rounded.time_s)) == pytest.approx(60.0, rel=1e-9)
    np.testing.assert_allclose(rounded.time_s, ref.time_s, atol=5e-4)  # the start rounded, nothing else
    np.testing.assert_array_equal(rounded.xyz_m, ref.xyz_m)


def test_trc_time_column_that_disagrees_with_its_header_rate(corpus, camargo):
    """A header claiming 100 Hz over a Time column stepping at 200 Hz: refused, naming both rates."""
    lines = corpus.text(CAMARGO_TRC).splitlines()
    values = lines[2].split("\t")
    values[0] = values[1] = "100"
    lines[2] = "\t".join(values)
    key = corpus.add(CAMARGO_TRC, "\n".join(lines) + "\n")
    subject, spec = _one_trial(camargo, key)
    with _raises(IngestError, corpus.path(key), "DataRate 100 Hz", "Time column steps at 200 Hz"):
        load_trial(subject, spec, corpus.manifest())


def test_up_axis_auto_refuses_a_tilted_lab(corpus, camargo):
    """The recording turned 45 deg about X: the pelvis stands ~0.7 m above the feet along both Y and Z,
    so `auto` cannot choose; the error gives the heights per axis and the way to declare it."""
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)

    def tilt(cells):
        out = cells[:2]
        for j in range(2, len(cells) - 2, 3):
            x, y, z = cells[j:j + 3]
            if not y.strip():
                out += [x, y, z]
                continue
            out += [x, f"{c * float(y) - s * float(z):.6f}", f"{s * float(y) + c * float(z):.6f}"]
        return out

    key = corpus.add(CAMARGO_TRC, _trc_edit(corpus.text(CAMARGO_TRC), tilt))
    subject, spec = _one_trial(camargo, key, up_axis="auto")
    with _raises(IngestError, corpus.path(key), "cannot detect the up axis", "Y +0.", "Z +0.",
                 "format.up_axis", "--up-axis"):
        load_trial(subject, spec, corpus.manifest())


def test_walking_trial_given_as_static(corpus):
    opencap = load_subject("opencap4")
    key = corpus.add(OPENCAP_WALK, corpus.text(OPENCAP_WALK))
    subject = dataclasses.replace(opencap, static=StaticSpec(key))
    with _raises(IngestError, corpus.path(key), "not a static (quiet standing) trial", "pelvis moving",
                 "> 0.1 m/s"):
        read_static_trial(subject, corpus.manifest())


def _mot_with_header(corpus: Corpus, replace: tuple[str, str] | None) -> str:
    text = corpus.text(CAMARGO_MOT)
    if replace is not None:
        assert replace[0] in text
        text = text.replace(replace[0], replace[1], 1)
    return corpus.add(CAMARGO_MOT, text)


def test_mot_radians_declared_as_degrees(corpus, camargo):
    key = _mot_with_header(corpus, ("inDegrees=no", "inDegrees=yes"))
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", angles=key),))
    with _raises(IngestError, corpus.path(key), "radians", "inDegrees=yes"):
        load_trial(subject, subject.trials[0], corpus.manifest())


def test_mot_degrees_declared_as_radians(corpus, camargo):
    text = corpus.text(CAMARGO_MOT)
    head, body = text.split("endheader\n", 1)
    rows = body.splitlines()
    names = rows[0].split("\t")
    angular = [j for j, n in enumerate(names) if n != "time" and not n.endswith(("_tx", "_ty", "_tz"))]
    converted = [rows[0]]
    for row in rows[1:]:
        cells = row.split("\t")
        for j in angular:
            cells[j] = f"{np.degrees(float(cells[j])):.6f}"
        converted.append("\t".join(cells))
    key = corpus.add(CAMARGO_MOT, head + "endheader\n" + "\n".join(converted) + "\n")
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", angles=key),))
    with _raises(IngestError, corpus.path(key), "exceeds 180 deg", "inDegrees"):
        load_trial(subject, subject.trials[0], corpus.manifest())


def test_mot_without_in_degrees_needs_a_declared_unit(corpus, camargo):
    key = _mot_with_header(corpus, ("inDegrees=no\n", ""))
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", angles=key),))
    with _raises(IngestError, corpus.path(key), "inDegrees", "angle_unit"):
        load_trial(subject, subject.trials[0], corpus.manifest())
    declared = dataclasses.replace(subject, format=dataclasses.replace(subject.format, angle_unit="rad"))
    knee = load_trial(declared, subject.trials[0], corpus.manifest()).angles["knee_flexion_left"]
    assert 50 < np.nanmax(knee) < 80  # declared unit honoured: radians converted to degrees


def test_mot_with_a_text_cell_names_its_column(corpus, camargo):
    text = corpus.text(CAMARGO_MOT)
    head, body = text.split("endheader\n", 1)
    rows = body.splitlines()
    knee = rows[0].split("\t").index("knee_angle_r")
    cells = rows[100].split("\t")
    cells[knee] = "abc"
    rows[100] = "\t".join(cells)
    key = corpus.add(CAMARGO_MOT, head + "endheader\n" + "\n".join(rows) + "\n")
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", angles=key),))
    with _raises(IngestError, corpus.path(key), "non-numeric values in columns ['knee_angle_r']"):
        load_trial(subject, subject.trials[0], corpus.manifest())


CAMARGO_GRF = "camargo2021_levelground/ID/levelground_ccw_fast_01_01_grf.mot"


def _mot_cells(text: str, column: str, rows: range, value: str) -> str:
    """A storage file's text with the cells of `column` in data `rows` (0-based, after the names) set
    to `value`."""
    head, body = text.split("endheader\n", 1)
    lines = body.splitlines()
    j = lines[0].split("\t").index(column)
    for k in rows:
        cells = lines[k + 1].split("\t")
        cells[j] = value
        lines[k + 1] = "\t".join(cells)
    return head + "endheader\n" + "\n".join(lines) + "\n"


@pytest.mark.parametrize("cell", ["NaN", ""])
def test_ik_mot_with_nan_cells_names_the_column_and_rows(corpus, camargo, cell):
    """Issue 34 case 2: NaN (or empty) knee cells inside an IK file flowed into kept cycles (a hole in the
    knee curve) and into ROM; refused, naming the file, the column and its rows and times."""
    text = _mot_cells(corpus.text(CAMARGO_MOT), "knee_angle_r", range(400, 481), cell)
    key = corpus.add(CAMARGO_MOT, text)
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", angles=key),))
    with _raises(IngestError, corpus.path(key), "empty or NaN cells: knee_angle_r rows 401-481",
                 "(2.005-2.405 s)", "every cell read must hold a number"):
        load_trial(subject, subject.trials[0], corpus.manifest())


def test_grf_mot_with_a_nan_vertical_force_names_the_column_and_rows(corpus, camargo):
    """A NaN vertical force silently turned every event kinematic (and `events --method force` printed a
    bare header); refused, naming the plate's column and rows."""
    text = _mot_cells(corpus.text(CAMARGO_GRF), "ground_force_2_vy", range(10, 12), "nan")
    key = corpus.add(CAMARGO_GRF, _mot_cells(text, "ground_force_2_vy", range(100, 301), "NaN"))
    markers = corpus.add(CAMARGO_TRC, corpus.text(CAMARGO_TRC))
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", markers, grf=key),))
    with _raises(IngestError, corpus.path(key), "ground_force_2_vy rows 11-12, 101-301 (0.055-1.505 s)"):
        load_trial(subject, subject.trials[0], corpus.manifest())


def test_mot_nan_in_the_last_row_is_not_called_truncated(corpus, camargo):
    """A NaN cell in a complete last row was reported as a truncated file; a row cut short still is."""
    text = corpus.text(CAMARGO_MOT)
    key = corpus.add(CAMARGO_MOT, _mot_cells(text, "knee_angle_l", range(3066, 3067), "NaN"))
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", angles=key),))
    with _raises(IngestError, corpus.path(key), "knee_angle_l rows 3067 (15.34-15.34 s)") as info:
        load_trial(subject, subject.trials[0], corpus.manifest())
    assert "truncated" not in str(info.value)
    key = corpus.add(CAMARGO_MOT, text.rstrip("\n").rsplit("\t", 3)[0] + "\n")  # the last row cut short
    with _raises(IngestError, corpus.path(key), "truncated: the last row is incomplete"):
        load_trial(subject, subject.trials[0], corpus.manifest())


def test_knee_sign_not_declared(corpus, camargo):
    """Camargo's knee flexion is negative in the file; a subject file that forgets to say so."""
    key = _mot_with_header(corpus, None)
    subject = dataclasses.replace(camargo, trials=(TrialSpec("bad", "free", angles=key),),
                                  format=FileFormat(up_axis="y", knee_flexion_sign=1))
    with _raises(IngestError, corpus.path(key), "knee_flexion_sign: -1"):
        load_trial(subject, subject.trials[0], corpus.manifest())


# --- gaps and missing markers ------------------------------------------------------------------

def _gap(text: str, marker: str, t0: float, t1: float) -> str:
    cols = _marker_columns(text, marker)

    def blank(cells):
        t = float(cells[1])
        if t0 <= t < t1:
            for j in cols:
                cells[j] = ""
        return cells

    return _trc_edit(text, blank)


def _kept_strides(corpus, camargo, ingest_params, text):
    key = corpus.add(CAMARGO_TRC, text)
    subject, spec = _one_trial(camargo, key)
    return process_trial(load_trial(subject, spec, corpus.manifest()), subject.markerset, ingest_params)


def test_short_marker_gap_is_filled(corpus, camargo, ingest_params, real):
    """A 50 ms heel dropout inside a kept stride: filled, events and strides unchanged within 10 ms."""
    text = corpus.text(CAMARGO_TRC)
    ref = _reference(camargo, real, ingest_params)
    out = _kept_strides(corpus, camargo, ingest_params, _gap(text, "L_Heel", 10.60, 10.65))
    assert out.strides["kept"].sum() == ref.strides["kept"].sum()
    hs = lambda ev: ev.query("event == 'heel_strike'")["time_s"].to_numpy()  # noqa: E731
    assert len(hs(out.events)) == len(hs(ref.events))
    assert np.max(np.abs(hs(out.events) - hs(ref.events))) < 0.01


def test_long_marker_gap_rejects_the_strides_it_touches(corpus, camargo, ingest_params):
    """A 0.5 s heel dropout: not invented; strides of that side over it are rejected as 'marker gap'."""
    text = corpus.text(CAMARGO_TRC)
    out = _kept_strides(corpus, camargo, ingest_params, _gap(text, "L_Heel", 10.4, 10.9))
    left = out.strides.query("side == 'left'")
    over = left[(left["t_start_s"] < 10.9) & (left["t_end_s"] > 10.4)]
    assert len(over) >= 1
    assert not over["kept"].any()
    assert set(over["reason"]) <= {"marker gap", "events missing"}
    assert "marker gap" in set(over["reason"]) | set(left["reason"])
    assert out.strides["kept"].sum() >= 4  # the rest of the trial still counts


def test_missing_heel_marker(corpus, camargo, ingest_params):
    text = corpus.text(CAMARGO_TRC)
    lines = text.splitlines()
    lines[3] = lines[3].replace("L_Heel", "L_Hee1")  # renamed: the marker set's heel is absent
    key = corpus.add(CAMARGO_TRC, "\n".join(lines) + "\n")
    subject, spec = _one_trial(camargo, key)
    with _raises(IngestError, corpus.path(key), "L_Heel"):
        process_trial(load_trial(subject, spec, corpus.manifest()), subject.markerset, ingest_params)


def test_trial_with_no_complete_stride(corpus, camargo, ingest_params):
    """Only the quiet standing at the start: the subject has nothing to offer downstream."""
    lines = corpus.text(CAMARGO_TRC).splitlines()
    header = lines[:5]
    values = header[2].split("\t")
    values[2] = "400"
    header[2] = "\t".join(values)
    rows = [line for line in lines[5:] if line.strip()][:400]  # the first 2 s: standing
    key = corpus.add(CAMARGO_TRC, "\n".join(header + rows) + "\n")
    subject, _ = _one_trial(camargo, key)
    with _raises(IngestError, str(camargo.path), "no steady complete stride"):
        process_subject(subject, corpus.manifest(), ingest_params)


# --- robot logs (synthetic: no robot log in the shared data, on the real trial's clock) ----------

CAMARGO_ROBOT = "camargo2021_levelground/Robot/levelground_ccw_fast_01_01_robot.csv"


def _robot_log(corpus: Corpus, end_early_s: float = 0.0, edit=None) -> str:
    """A 100 Hz robot log over the real Camargo trial's span; `edit(header, rows)` alters its text."""
    mocap = read_trc(corpus.real.resolve(CAMARGO_TRC)).time_s
    t = np.arange(mocap[0], mocap[-1] - end_early_s + 0.005, 0.01)
    header = ["time [s]", "arm_forward [m]", "arm_lateral [m]", "arm_vertical [m]", "base_x [m]",
              "base_y [m]", "base_yaw [rad]"]
    rows = [[f"{x:.4f}", "0.02", "-0.01", "0.005", f"{1.2 * x:.4f}", "0", "0"] for x in t]
    if edit is not None:
        header, rows = edit(header, rows)
    return corpus.add(CAMARGO_ROBOT, "\n".join(",".join(r) for r in [header, *rows]) + "\n")


def test_robot_log_missing_column(corpus):
    key = _robot_log(corpus, edit=lambda h, rows: (h[:-1], [r[:-1] for r in rows]))
    with _raises(IngestError, corpus.path(key), "missing required columns: base_yaw"):
        read_robot_log(corpus.manifest().resolve(key))


def test_robot_log_arm_in_degrees(corpus):
    key = _robot_log(corpus, edit=lambda h, rows: ([c.replace("arm_forward [m]", "arm_forward [deg]")
                                                     for c in h], rows))
    with _raises(IngestError, corpus.path(key), "'arm_forward'", "'deg'", "'m', 'cm', 'mm'"):
        read_robot_log(corpus.manifest().resolve(key))


def test_robot_log_time_not_increasing(corpus):
    def swap(header, rows):
        rows[100], rows[101] = rows[101], rows[100]
        return header, rows

    key = _robot_log(corpus, edit=swap)
    with _raises(IngestError, corpus.path(key), "time not strictly increasing", "line 103"):
        read_robot_log(corpus.manifest().resolve(key))


def test_robot_log_shorter_than_the_mocap(corpus):
    key = _robot_log(corpus, end_early_s=2.0)
    log = read_robot_log(corpus.manifest().resolve(key))
    mocap = read_trc(corpus.real.resolve(CAMARGO_TRC)).time_s
    with _raises(IngestError, corpus.path(key), "robot log covers", "the mocap trial"):
        robot_table(log, mocap, "camargo", "pid", "bad")


def test_robot_log_partial_load_cell(corpus):
    key = _robot_log(corpus, edit=lambda h, rows: ([*h, "harness_fx [N]", "harness_fy [N]"],
                                                    [[*r, "1.0", "2.0"] for r in rows]))
    with _raises(IngestError, corpus.path(key), "partial", "harness_fz"):
        read_robot_log(corpus.manifest().resolve(key))


def test_robot_log_flag_not_zero_or_one(corpus):
    key = _robot_log(corpus, edit=lambda h, rows: ([*h, "fall [-]"], [[*r, "2" if i == 5 else "0"]
                                                                       for i, r in enumerate(rows)]))
    with _raises(IngestError, corpus.path(key), "flag 'fall'"):
        read_robot_log(corpus.manifest().resolve(key))


def test_robot_log_unknown_column(corpus):
    key = _robot_log(corpus, edit=lambda h, rows: ([*h, "battery [V]"], [[*r, "24"] for r in rows]))
    with _raises(IngestError, corpus.path(key), "unknown column 'battery'", "arm_forward"):
        read_robot_log(corpus.manifest().resolve(key))


def test_robot_log_non_numeric_cell(corpus):
    def garble(header, rows):
        rows[10][1] = "n/a"
        return header, rows

    key = _robot_log(corpus, edit=garble)
    with _raises(IngestError, corpus.path(key), "non-numeric cell 'n/a'", "arm_forward"):
        read_robot_log(corpus.manifest().resolve(key))


def test_robot_markers_absent_from_the_marker_file(corpus, camargo, ingest_params, real):
    from ingest.subject import RobotMarkers

    subject = dataclasses.replace(camargo, robot_markers=RobotMarkers("MRBA_front", "MRBA_rear", "MRBA_arm",
                                                                      (0.55, 0.0, 0.45)))
    spec = TrialSpec(id="bad", condition="pid", markers=CAMARGO_TRC)
    with _raises(IngestError, "levelground_ccw_fast_01_01.trc", "robot markers", "MRBA_front"):
        process_trial(load_trial(subject, spec, real), subject.markerset, ingest_params)


# --- subject files and marker sets ----------------------------------------------------------------

def _subject_file(tmp_path: Path, **changes) -> Path:
    doc = yaml.safe_load((ROOT / "data" / "subjects" / "camargo.yaml").read_text())
    doc.update(changes)
    (tmp_path / "camargo.yaml").write_text(yaml.safe_dump(doc))
    return tmp_path / "camargo.yaml"


@pytest.mark.parametrize(("field", "value", "accepted"), [("height_m", 168.0, "0.5-2.5 m"),
                                                          ("mass_kg", 2.5, "10-300 kg")])
def test_body_size_out_of_range_names_the_accepted_range(tmp_path, field, value, accepted):
    """Issue 34 case 3: a height in centimetres was refused without the accepted range."""
    path = _subject_file(tmp_path, **{field: value})
    with _raises(SubjectError, str(path), f"{field} {value:g} is outside the accepted {accepted}"):
        load_subject("camargo", tmp_path)


def test_mass_in_pounds_is_refused_against_the_force_plates(real, ingest_params):
    """Issue 34 case 3: opencap4's 62.6 kg typed as pounds (x 2.2) was accepted while the plates weigh
    her near 60 kg; refused naming both numbers. The mass as given passes the same check."""
    opencap = load_subject("opencap4")
    opencap = dataclasses.replace(opencap, trials=tuple(t for t in opencap.trials
                                                        if t.id in ("walking4", "walkingTS1", "walkingTS2")))
    assert all(t.grf for t in opencap.trials) and len(opencap.trials) == 3
    tables = process_subject(opencap, real, ingest_params)
    assert tables.strides["kept"].any()
    pounds = dataclasses.replace(opencap, mass_kg=round(opencap.mass_kg * 2.2, 2))
    with _raises(SubjectError, str(opencap.path), "mass_kg 137.72 but the force plates weigh the subject at ",
                 "kg (median of 3 strides wholly on plates)", "more than 10%") as info:
        process_subject(pounds, real, ingest_params)
    weighed = float(str(info.value).split("weigh the subject at ")[1].split(" kg")[0])
    assert abs(weighed / opencap.mass_kg - 1) < 0.10  # the plates agree with the mass as given


def test_robot_log_on_a_free_trial(tmp_path):
    doc = yaml.safe_load((ROOT / "data" / "subjects" / "camargo.yaml").read_text())
    trials = [{**doc["trials"][0], "robot_log": "some/robot.csv"}]
    path = _subject_file(tmp_path, trials=trials)
    with _raises(SubjectError, str(path), "free walking but has a robot_log"):
        load_subject("camargo", tmp_path)


def test_robot_markers_without_the_neutral_point(tmp_path):
    path = _subject_file(tmp_path, robot_markers={"base_front": "A", "base_rear": "B", "arm_end": "C"})
    with _raises(SubjectError, str(path), "robot_markers needs", "neutral_in_base_m"):
        load_subject("camargo", tmp_path)


def test_marker_set_file_missing_roles(tmp_path):
    from ingest.subject import load_markerset

    roles = yaml.safe_load((ROOT / "data" / "markersets" / "camargo.yaml").read_text())
    roles = {k: v for k, v in roles.items() if not k.startswith("psis")}
    path = tmp_path / "lab.yaml"
    path.write_text(yaml.safe_dump(roles))
    with _raises(SubjectError, str(path), "missing roles", "psis_left", "psis_right"):
        load_markerset(str(path))


def test_unknown_marker_set_lists_the_shipped_ones():
    from ingest.subject import load_markerset

    with _raises(SubjectError, "nolab", "unknown marker set", "camargo"):
        load_markerset("nolab")


def test_grf_file_without_plate_columns(corpus, camargo):
    from ingest.canonical import plates_from_grf
    from ingest.readers import read_mot

    text = corpus.text(CAMARGO_MOT)  # joint angles where ground reactions belong
    key = corpus.add("camargo2021_levelground/ID/not_a_grf.mot", text)
    with _raises(IngestError, corpus.path(key), "no force plate columns"):
        plates_from_grf(read_mot(corpus.manifest().resolve(key)), camargo.format, 0.0)


# --- registry and manifest ---------------------------------------------------------------------

def test_unknown_subject_lists_known_ones():
    with _raises(SubjectError, "nosuchsubject", "camargo", "opencap4"):
        load_subject("nosuchsubject")


def test_hash_mismatch(corpus, camargo):
    key = corpus.add(CAMARGO_TRC, corpus.text(CAMARGO_TRC))
    (corpus.root / "mirror" / key).write_text(corpus.text(CAMARGO_TRC).replace("0.", "1.", 1))
    with _raises(ManifestError, corpus.path(key), "sha256 mismatch"):
        corpus.manifest().resolve(key)


def test_a_changed_marker_file_is_refused_for_its_hash_not_its_contents(corpus, camargo):
    # load_trial parses the marker file while another thread checks its sha256: a file that is
    # not the manifest's (here also cut mid-row) is refused as such, never read as truncated
    text = corpus.text(CAMARGO_TRC)
    key = corpus.add(CAMARGO_TRC, text)
    (corpus.root / "mirror" / key).write_text(text[: len(text) // 2])
    subject, spec = _one_trial(camargo, key)
    with _raises(ManifestError, corpus.path(key), "sha256 mismatch"):
        load_trial(subject, spec, corpus.manifest())


def test_missing_file_and_no_download(corpus):
    key = corpus.add("nowhere/gone.trc", "x")
    (corpus.root / "mirror" / key).unlink()
    with _raises(ManifestError, key, "download", UNREACHABLE_URL):
        corpus.manifest().resolve(key)
    assert not any((corpus.root / "cache").rglob("*.part"))  # nothing half-downloaded left


def test_file_not_in_manifest(corpus):
    with _raises(ManifestError, "some/file.trc", "not listed"):
        corpus.manifest().resolve("some/file.trc")


def test_every_corpus_error_is_a_gaitloop_error():
    assert issubclass(IngestError, GaitloopError)
    assert issubclass(ManifestError, GaitloopError) and issubclass(SubjectError, GaitloopError)


# --- more files and fields that cannot be trusted (issue 34, deliverable 4) ---------------------

def _trc_header(text: str, column: str, value: str) -> str:
    """A TRC text with the header value of `column` (line 3, named on line 2) set to `value`."""
    lines = text.splitlines()
    cells = lines[2].split("\t")
    cells[lines[1].split("\t").index(column)] = value
    return "\n".join([*lines[:2], "\t".join(cells), *lines[3:]]) + "\n"


def _trc_row_time(text: str, row: int, value: str) -> str:
    """A TRC text with the Time cell of data row `row` (1-based, as the reader names rows) set."""
    lines = text.splitlines()
    data = [k for k in range(5, len(lines)) if lines[k].strip()]
    cells = lines[data[row - 1]].split("\t")
    cells[1] = value
    lines[data[row - 1]] = "\t".join(cells)
    return "\n".join(lines) + "\n"


def test_trc_with_a_duplicated_marker_name(corpus):
    """Two markers of one name were read as two markers, the role taking whichever came first."""
    lines = corpus.text(CAMARGO_TRC).splitlines()
    names = lines[3].split("\t")
    second = next(j for j in range(3, len(names)) if names[j])  # the second marker's name cell
    names[second] = names[2]
    key = corpus.add(CAMARGO_TRC, "\n".join([*lines[:3], "\t".join(names), *lines[4:]]) + "\n")
    with _raises(IngestError, corpus.path(key), f"duplicate marker name(s) on line 4: {names[2]}"):
        read_trc(corpus.path(key))


@pytest.mark.parametrize("rate", ["0", "-200"])
def test_trc_header_rate_not_positive(corpus, rate):
    """A DataRate of 0 gave a message about 'nan s off the header's nan s'; refused as a rate."""
    key = corpus.add(CAMARGO_TRC, _trc_header(corpus.text(CAMARGO_TRC), "DataRate", rate))
    with _raises(IngestError, corpus.path(key), f"header DataRate {rate} Hz: must be a positive number"):
        read_trc(corpus.path(key))


def test_trc_time_stepping_back(corpus):
    """A Time column that steps back (a spliced file) was reported as a wrong DataRate."""
    text = corpus.text(CAMARGO_TRC)
    key = corpus.add(CAMARGO_TRC, _trc_row_time(text, 10, "0.040000"))
    with _raises(IngestError, corpus.path(key), "Time column not strictly increasing: row 10 is at 0.04 s "
                                                "after 0.045 s"):
        read_trc(corpus.path(key))


def test_trc_with_an_infinite_coordinate(corpus):
    """A coordinate written as 1e400 (read as infinity) was accepted and filtered into every frame."""
    text = corpus.text(CAMARGO_TRC)
    j = _marker_columns(text, "L_Heel")[2]
    lines = text.splitlines()
    cells = lines[25].split("\t")
    cells[j] = "1e400"
    lines[25] = "\t".join(cells)
    key = corpus.add(CAMARGO_TRC, "\n".join(lines) + "\n")
    with _raises(IngestError, corpus.path(key), "marker L_Heel has an infinite coordinate at row",
                 "empty cell"):
        read_trc(corpus.path(key))


def test_trc_units_in_inches(corpus):
    key = corpus.add(CAMARGO_TRC, _trc_header(corpus.text(CAMARGO_TRC), "Units", "in"))
    with _raises(IngestError, corpus.path(key), "unknown Units 'in'", "'cm', 'm', 'mm'"):
        read_trc(corpus.path(key))


def test_trc_frame_count_not_a_number(corpus):
    key = corpus.add(CAMARGO_TRC, _trc_header(corpus.text(CAMARGO_TRC), "NumFrames", "many"))
    with _raises(IngestError, corpus.path(key), "bad header value", "'many'"):
        read_trc(corpus.path(key))


def test_trc_declaring_fewer_markers_than_it_names(corpus):
    key = corpus.add(CAMARGO_TRC, _trc_header(corpus.text(CAMARGO_TRC), "NumMarkers", "27"))
    with _raises(IngestError, corpus.path(key), "header declares 27 markers, line 4 names 28"):
        read_trc(corpus.path(key))


def test_ik_mot_with_a_duplicated_column(corpus):
    """Pandas renamed the second 'knee_angle_r' to 'knee_angle_r.1': one knee curve silently lost."""
    from ingest.readers import read_mot

    head, body = corpus.text(CAMARGO_MOT).split("endheader\n", 1)
    lines = body.splitlines()
    names = lines[0].split("\t")
    names[names.index("knee_angle_l")] = "knee_angle_r"
    key = corpus.add(CAMARGO_MOT, head + "endheader\n" + "\n".join(["\t".join(names), *lines[1:]]) + "\n")
    with _raises(IngestError, corpus.path(key), "duplicate column(s) knee_angle_r"):
        read_mot(corpus.path(key))


def test_grf_mot_whose_row_count_disagrees_with_its_header(corpus):
    from ingest.readers import read_mot

    text = corpus.text(CAMARGO_GRF)
    key = corpus.add(CAMARGO_GRF, text.replace("nRows=3067", "nRows=3167", 1))
    with _raises(IngestError, corpus.path(key), "header declares 3167 rows, file holds 3067"):
        read_mot(corpus.path(key))


def test_grf_mot_with_time_stepping_back(corpus):
    from ingest.readers import read_mot

    head, body = corpus.text(CAMARGO_GRF).split("endheader\n", 1)
    lines = body.splitlines()
    cells = lines[11].split("\t")
    cells[0] = lines[9].split("\t")[0]
    lines[11] = "\t".join(cells)
    key = corpus.add(CAMARGO_GRF, head + "endheader\n" + "\n".join(lines) + "\n")
    with _raises(IngestError, corpus.path(key), "time column is not strictly increasing"):
        read_mot(corpus.path(key))


def test_grf_mot_without_endheader(corpus):
    from ingest.readers import read_mot

    key = corpus.add(CAMARGO_GRF, corpus.text(CAMARGO_GRF).replace("endheader\n", "", 1))
    with _raises(IngestError, corpus.path(key), "no 'endheader' line"):
        read_mot(corpus.path(key))


def _subject_doc() -> dict:
    return yaml.safe_load((ROOT / "data" / "subjects" / "camargo.yaml").read_text())


def _write_subject(tmp_path: Path, doc) -> Path:
    (tmp_path / "camargo.yaml").write_text(yaml.safe_dump(doc))
    return tmp_path / "camargo.yaml"


def _edit_trial(**changes):
    def edit(doc):
        doc["trials"][0].update(changes)
    return edit


def _without(section: str, key: str):
    def edit(doc):
        doc[section].pop(key)
    return edit


@pytest.mark.parametrize(("edit", "fragments"), [
    (lambda d: d.update(mass_lb=165),
     ["subject file: unknown key(s) 'mass_lb'", "known: id, height_m, mass_kg"]),
    (lambda d: d.update(height_m="tall"), ["height_m 'tall' is not a number"]),
    (lambda d: d.update(mass_kg=None), ["missing required field 'mass_kg'"]),
    (lambda d: d.update(trials={"walk": "a.trc"}), ["trials must be a list of trials"]),
    (lambda d: d.update(trials=["walk.trc"]), ["trials[0] must be a mapping of id, condition", "'walk.trc'"]),
    (lambda d: d["trials"].append(dict(d["trials"][0])),
     ["trial id(s) 'levelground_ccw_fast_01_01' listed twice"]),
    (_edit_trial(marker="x.trc"), ["trials[0]: unknown key(s) 'marker'", "known: id, condition, markers"]),
    (lambda d: d["format"].update(upaxis="y"), ["format: unknown key(s) 'upaxis'", "known: up_axis"]),
    (lambda d: d["format"].update(knee_flexion_sign="minus"), ["knee_flexion_sign 1 or -1", "'minus'"]),
    (lambda d: d["format"].update(angle_unit="grad"), ["format.angle_unit must be deg or rad, not 'grad'"]),
    (lambda d: d.update(static="maybe"), ["static must be auto, none or a mapping", "'maybe'"]),
    (_without("static", "markers"), ["static: missing required field 'markers'"]),
    (lambda d: d["static"].update(window_s=[3.3, 1.5]),
     ["static.window_s must be [start, end]", "[3.3, 1.5]"]),
    (lambda d: d["static"].update(window=[1.5, 3.3]), ["static: unknown key(s) 'window'", "window_s"]),
], ids=["unknown key", "height text", "mass empty", "trials mapping", "trial a string", "trial id twice",
        "trial unknown key", "format unknown key", "knee sign text", "angle unit", "static text",
        "static without markers", "static window reversed", "static unknown key"])
def test_subject_file_field_refused_naming_file_and_key(tmp_path, edit, fragments):
    """Each of these was ignored (a misspelt key, a doubled trial, an angle unit read as radians) or
    ended in a raw ValueError / AttributeError; refused naming the subject file and the field."""
    doc = _subject_doc()
    edit(doc)
    path = _write_subject(tmp_path, doc)
    with _raises(SubjectError, str(path), *fragments):
        load_subject("camargo", tmp_path)


def test_subject_file_that_is_a_list(tmp_path):
    (tmp_path / "camargo.yaml").write_text("- camargo\n- 1.80\n")
    with _raises(SubjectError, str(tmp_path / "camargo.yaml"), "subject file must be a mapping"):
        load_subject("camargo", tmp_path)


def test_marker_set_role_naming_a_marker_missing_from_the_file(tmp_path, corpus, camargo, ingest_params):
    """A marker set whose heel role names a marker the file does not hold: refused naming the file and
    the missing marker, not a traceback from inside the landmarks."""
    from ingest.subject import load_markerset

    roles = yaml.safe_load((ROOT / "data" / "markersets" / "camargo.yaml").read_text())
    roles["heel_left"] = "L_Heel_typo"
    (tmp_path / "lab.yaml").write_text(yaml.safe_dump(roles))
    key = corpus.add(CAMARGO_TRC, corpus.text(CAMARGO_TRC))
    lab = load_markerset(str(tmp_path / "lab.yaml"))
    subject, spec = _one_trial(dataclasses.replace(camargo, markerset=lab), key)
    with _raises(IngestError, corpus.path(key), "missing: L_Heel_typo"):
        process_trial(load_trial(subject, spec, corpus.manifest()), subject.markerset, ingest_params)
