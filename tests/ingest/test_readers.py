"""Readers on the real files (TRC, MOT) and round trips through C3D and the documented CSV layout,
plus sign and unit normalisation of joint angles from marker-based and markerless sources."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ingest.canonical import canonical_angles, load_trial
from ingest.manifest import Manifest, Source, sha256_of
from ingest.process import IngestParams, process_trial
from ingest.readers import read_c3d, read_csv, read_markers, read_mot, read_trc
from ingest.subject import FileFormat, TrialSpec, load_subject

ROOT = Path(__file__).resolve().parents[2]
CAMARGO_TRC = "camargo2021_levelground/MarkerData/levelground_ccw_fast_01_01.trc"
CAMARGO_MOT = "camargo2021_levelground/IK/levelground_ccw_fast_01_01_ik.mot"
OPENCAP_STATIC = "opencap_labval_subject4/MarkerData/static1.trc"
MARKERLESS_MOT = "opencap_markerless_walking/walking1_videoAndMocap.mot"


@pytest.fixture(scope="module")
def manifest() -> Manifest:
    return Manifest.load()


def test_trc_header_and_shape(manifest):
    trc = read_trc(manifest.resolve(CAMARGO_TRC))
    assert trc.rate_hz == 200 and trc.declared_unit == "m"
    assert trc.xyz_m.shape == (3067, 28, 3) and len(trc.names) == 28
    assert np.allclose(np.diff(trc.time_s), 1 / 200)
    static = read_trc(manifest.resolve(OPENCAP_STATIC))
    assert static.rate_hz == 100 and static.xyz_m.shape == (517, 55, 3)
    assert {"L_mknee", "r_mknee", "L_mankle", "r_mankle"} <= set(static.names)


def test_mot_reports_its_units(manifest):
    ik = read_mot(manifest.resolve(CAMARGO_MOT))
    assert ik.in_degrees is False and len(ik.table) == 3067 and ik.rate_hz == pytest.approx(200)
    markerless = read_mot(manifest.resolve(MARKERLESS_MOT))
    assert markerless.in_degrees is True and markerless.rate_hz == pytest.approx(100)


def _pandas_rows(path: Path) -> np.ndarray:
    """The .trc's data rows as pandas' C parser reads them (the reader's fallback)."""
    return pd.read_csv(path, sep="\t", header=None, skiprows=5, dtype=float).to_numpy()


def test_trc_fast_rows_equal_pandas_also_with_trailing_tabs(tmp_path, manifest):
    """The strict fast reader gives pandas' floats bit for bit (gaps as NaN), also for rows ending in
    a tab (kgc6's exporter); Camargo's file has gaps, so NaN placement is checked too."""
    path = manifest.resolve(CAMARGO_TRC)
    rows = _pandas_rows(path)
    assert np.isnan(rows).any()
    trc = read_trc(path)
    np.testing.assert_array_equal(trc.xyz_m.reshape(len(rows), -1), rows[:, 2:])
    lines = path.read_text().splitlines()
    tabbed = tmp_path / "tabbed.trc"
    tabbed.write_text("\n".join(lines[:5] + [ln + "\t" if ln else ln for ln in lines[5:]]) + "\n")
    np.testing.assert_array_equal(read_trc(tabbed).xyz_m, trc.xyz_m)
    quoted = tmp_path / "quoted.trc"  # an unmatched quote in the header does not join lines
    quoted.write_text("\n".join([lines[0] + '\t"C:\\trials'] + lines[1:]) + "\n")
    np.testing.assert_array_equal(read_trc(quoted).xyz_m, trc.xyz_m)


def test_strict_rows_refuse_what_pandas_must_judge():
    """Ragged rows, text cells and a filled cell past the declared width return None (the readers
    then parse with pandas and name the problem); empty cells are NaN; cells not kept are not read."""
    from ingest.readers.delimited import strict_float_rows

    ok = strict_float_rows(b"0\t1.5\t\n1\t2.5\t3\n", 3)
    np.testing.assert_array_equal(ok, [[0, 1.5, np.nan], [1, 2.5, 3]])
    assert strict_float_rows(b"0\t1.5\t2\n1\t2.5\n", 3) is None
    assert strict_float_rows(b"0\t1.5\tx\n", 3) is None
    assert strict_float_rows(b"0\t1.5\t2\t9\n", 3) is None
    np.testing.assert_array_equal(strict_float_rows(b"0\t1.5\tx\n", 3, keep=[0, 1]), [[0, 1.5]])


def test_mot_columns_keep_time_and_the_named_ones(manifest):
    """`read_mot(columns=...)` keeps `time` and the columns picked, with the full read's values."""
    full = read_mot(manifest.resolve(CAMARGO_MOT))
    some = read_mot(manifest.resolve(CAMARGO_MOT), columns=lambda c: c.startswith("knee_angle"))
    assert list(some.table.columns) == ["time", "knee_angle_r", "knee_angle_l"]
    pd.testing.assert_frame_equal(some.table, full.table[list(some.table.columns)])


def _swing_peak(knee: np.ndarray) -> float:
    return float(np.nanmax(knee))


def test_knee_flexion_of_marker_based_radians_negative_source(manifest):
    """Camargo IK: radians, knee flexion negative -> degrees, flexion positive, 50-75 deg in swing."""
    fmt = load_subject("camargo").format
    mot = read_mot(manifest.resolve(CAMARGO_MOT))
    angles = canonical_angles(mot, fmt, None)
    steady = (mot.time_s > 5.4) & (mot.time_s < 7.4)  # two steady strides before the turn
    for side in ("left", "right"):
        knee = angles[f"knee_flexion_{side}"]
        assert 50 < _swing_peak(knee[steady]) < 75
        assert np.nanpercentile(knee, 5) > -10  # no hyperextension: the sign was flipped


def test_knee_flexion_of_markerless_degrees_positive_source(manifest):
    """OpenCap video-based IK: degrees, knee flexion positive -> unchanged, peak 50-75 deg."""
    mot = read_mot(manifest.resolve(MARKERLESS_MOT))
    angles = canonical_angles(mot, FileFormat(up_axis="y", knee_flexion_sign=1), None)
    for side in ("left", "right"):
        knee = angles[f"knee_flexion_{side}"]
        assert 50 < _swing_peak(knee) < 75
        assert np.nanmin(knee) > -10
        raw = mot.table[f"knee_angle_{side[0]}"].to_numpy(float)
        np.testing.assert_allclose(knee, raw)  # already canonical: nothing changed
        hip = angles[f"hip_flexion_{side}"]
        assert 15 < np.nanmax(hip) < 45 and -30 < np.nanmin(hip) < 0


def _roundtrip_trial(tmp_path: Path, key: str, manifest_src: Manifest, ingest_params: IngestParams):
    """Process `key` (written under tmp_path) as the Camargo trial's markers, no GRF."""
    subject = load_subject("camargo")
    path = tmp_path / key
    local = Manifest({key: Source(key, "file:///nowhere", sha256_of(path))}, tmp_path, tmp_path / "cache")
    spec = TrialSpec(id="roundtrip", condition="free", markers=key)
    subject = dataclasses.replace(subject, trials=(spec,))
    return process_trial(load_trial(subject, spec, local), subject.markerset, ingest_params)


def _reference(manifest: Manifest, ingest_params: IngestParams):
    subject = load_subject("camargo")
    spec = TrialSpec(id="roundtrip", condition="free", markers=CAMARGO_TRC)
    subject = dataclasses.replace(subject, trials=(spec,))
    return process_trial(load_trial(subject, spec, manifest), subject.markerset, ingest_params)


def test_c3d_round_trip_gives_the_same_strides(tmp_path, manifest, ingest_params):
    """The Camargo markers written to C3D in millimetres (float32, as Vicon does) read back to
    within 0.1 mm and give the same kept strides."""
    import ezc3d

    trc = read_trc(manifest.resolve(CAMARGO_TRC))
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [trc.rate_hz]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = trc.names
    points = np.ones((4, len(trc.names), trc.xyz_m.shape[0]))
    points[:3] = np.transpose(trc.xyz_m * 1000.0, (2, 1, 0))
    c3d["data"]["points"] = points
    c3d.add_parameter("POINT", "UNITS", "mm")
    key = "c3d/levelground.c3d"
    (tmp_path / "c3d").mkdir()
    c3d.write(str(tmp_path / key))

    back = read_c3d(tmp_path / key).markers
    assert back.names == trc.names and back.declared_unit == "mm" and back.rate_hz == trc.rate_hz
    assert np.nanmax(np.abs(back.xyz_m - trc.xyz_m)) < 1e-4
    assert np.array_equal(np.isnan(back.xyz_m), np.isnan(trc.xyz_m))  # gaps stay gaps

    out = _roundtrip_trial(tmp_path, key, manifest, ingest_params).strides
    ref = _reference(manifest, ingest_params).strides
    assert out["kept"].sum() == ref["kept"].sum() >= 8
    np.testing.assert_allclose(out.loc[out["kept"], "stride_length_m"],
                               ref.loc[ref["kept"], "stride_length_m"], atol=1e-3)


def test_csv_round_trip_in_centimetres(tmp_path, manifest, ingest_params):
    """The documented CSV layout with centimetre columns and one angle in radians."""
    trc = read_trc(manifest.resolve(CAMARGO_TRC))
    columns = {"time_s": trc.time_s}
    for j, name in enumerate(trc.names):
        for k, axis in enumerate("xyz"):
            columns[f"{name}_{axis}_cm"] = trc.xyz_m[:, j, k] * 100.0
    columns["knee_flexion_left_rad"] = np.full(len(trc.time_s), 0.5)
    key = "csv/levelground.csv"
    (tmp_path / "csv").mkdir()
    pd.DataFrame(columns).to_csv(tmp_path / key, index=False)

    rec = read_csv(tmp_path / key)
    assert set(rec.markers.names) == set(trc.names) and rec.markers.declared_unit == "cm"
    assert rec.markers.rate_hz == pytest.approx(200)
    order = [rec.markers.names.index(n) for n in trc.names]
    np.testing.assert_allclose(rec.markers.xyz_m[:, order], trc.xyz_m, atol=1e-9)
    assert rec.angles_deg["knee_flexion_left"][0] == pytest.approx(np.degrees(0.5))
    assert read_markers(tmp_path / key).names == rec.markers.names

    out = _roundtrip_trial(tmp_path, key, manifest, ingest_params).strides
    ref = _reference(manifest, ingest_params).strides
    assert out["kept"].tolist() == ref["kept"].tolist()


def test_csv_with_an_unknown_column_names_it(tmp_path):
    path = tmp_path / "bad.csv"
    pd.DataFrame({"time_s": [0.0, 0.01], "LHeel_x": [1.0, 1.0]}).to_csv(path, index=False)
    from ingest.errors import IngestError

    with pytest.raises(IngestError, match="LHeel_x"):
        read_csv(path)
