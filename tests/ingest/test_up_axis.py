"""Up axis `auto` (ingest/canonical.py): detected from where the pelvis stands above the feet,
logged and kept in the provenance; a declared axis still wins and is still checked."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from ingest.canonical import detect_up_axis, load_trial, up_to_z, z_up_to
from ingest.errors import IngestError
from ingest.manifest import Manifest
from ingest.readers import read_trc
from ingest.subject import FileFormat, load_subject


@pytest.fixture(scope="module")
def manifest() -> Manifest:
    return Manifest.load()


@pytest.fixture(scope="module")
def camargo():
    return load_subject("camargo")


def _auto(subject):
    return dataclasses.replace(subject, format=dataclasses.replace(subject.format, up_axis="auto"))


def test_auto_detects_y_logs_it_and_reads_as_declared(camargo, manifest, caplog):
    with caplog.at_level(logging.INFO, logger="gaitloop.ingest"):
        auto = load_trial(_auto(camargo), camargo.trials[0], manifest)
    declared = load_trial(camargo, camargo.trials[0], manifest)
    assert auto.provenance[0].reader == "markers:trc up=y(auto)"
    assert declared.provenance[0].reader == "markers:trc up=y"
    assert any("up axis Y detected" in r.getMessage() for r in caplog.records)
    for name in ("L_Heel", "R_ASIS"):
        np.testing.assert_array_equal(auto.markers[name], declared.markers[name])
    assert auto.plates is not None
    np.testing.assert_array_equal(auto.plates.fz_n, declared.plates.fz_n)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_auto_detects_each_axis_of_a_rotated_recording(camargo, manifest, axis):
    table = read_trc(manifest.resolve(camargo.trials[0].markers))
    in_axis = z_up_to(up_to_z(table.xyz_m, "y"), axis)  # the recording as an `axis`-up lab wrote it
    found, heights = detect_up_axis(in_axis, table.names, camargo.markerset, "rotated.trc")
    assert found == axis
    assert 0.8 < heights[axis] < 1.1  # camargo's pelvis centre stands ~0.9 m above the foot markers
    np.testing.assert_allclose(up_to_z(in_axis, axis), up_to_z(table.xyz_m, "y"), atol=1e-12)


def test_upside_down_recording_names_heights_and_the_fix(camargo, manifest):
    table = read_trc(manifest.resolve(camargo.trials[0].markers))
    flipped = table.xyz_m * np.array([1.0, -1.0, -1.0])  # Y down
    with pytest.raises(IngestError) as info:
        detect_up_axis(flipped, table.names, camargo.markerset, "flipped.trc")
    message = str(info.value)
    assert message.startswith("flipped.trc") and "cannot detect the up axis" in message
    assert "Y -0.9" in message  # the measured height along each axis
    assert "format.up_axis" in message and "--up-axis" in message


def test_declared_axis_wins_and_is_checked(camargo, manifest):
    wrong = dataclasses.replace(camargo, format=dataclasses.replace(camargo.format, up_axis="z"))
    with pytest.raises(IngestError, match=r"Z declared.*format\.up_axis are wrong.*--up-axis"):
        load_trial(wrong, camargo.trials[0], manifest)


def test_subject_files_default_to_auto(camargo, tmp_path):
    text = camargo.path.read_text()
    assert "up_axis: y" in text  # the registered subjects keep their declared axis
    assert camargo.format.up_axis == "y"
    (tmp_path / "camargo.yaml").write_text(text.replace("  up_axis: y", "  # no up axis"))
    assert load_subject("camargo", tmp_path).format.up_axis == "auto"
    assert FileFormat().up_axis == "z"  # a bare FileFormat (events without --up-axis) stays Z up
