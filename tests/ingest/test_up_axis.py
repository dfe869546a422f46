"""Up axis `auto` (ingest/canonical.py): detected from where the pelvis stands above the feet,
logged and kept in the provenance; a declared axis still wins and is still checked."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from ingest.canonical import detect_up_axis, load_trial, up_to_z, z_up_to
from ingest.errors import IngestError
from ingest.manifest import Manifest, Source, sha256_of
from ingest.process import IngestParams, ProcessedTrial, process_trial
from ingest.readers import read_trc
from ingest.readers.trc import write_trc
from ingest.subject import FileFormat, Subject, TrialSpec, load_subject


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


@pytest.mark.parametrize("subject_id", ["opencap4", "camargo"])
def test_y_up_file_and_its_z_up_copy_give_the_same_events_with_auto(subject_id, manifest, ingest_params,
                                                                     tmp_path):
    """Issue 12: a real Y-up walk and its copy rewritten Z up, both read with up axis `auto` through the
    subject machinery (markers only, as `events FILE` reads them): the same events and strides."""
    subject = _auto(load_subject(subject_id))
    key = subject.trials[0].markers
    table = read_trc(manifest.resolve(key))
    copy = write_trc(tmp_path / "zup.trc", table.time_s, table.names, up_to_z(table.xyz_m, "y"),
                     unit=table.declared_unit)
    copies = Manifest({"zup.trc": Source("zup.trc", copy.as_uri(), sha256_of(copy))}, tmp_path, tmp_path)
    yup = _markers_only(subject, key, manifest, ingest_params)
    z = _markers_only(subject, "zup.trc", copies, ingest_params)
    assert (yup.trial.provenance[0].reader, z.trial.provenance[0].reader) == (
        "markers:trc up=y(auto)", "markers:trc up=z(auto)")
    assert len(yup.events) > 4
    cols = ["side", "event"]
    assert yup.events[cols].values.tolist() == z.events[cols].values.tolist()
    np.testing.assert_allclose(z.events["time_s"], yup.events["time_s"], atol=1.0 / table.rate_hz)
    assert z.strides["kept"].tolist() == yup.strides["kept"].tolist()
    np.testing.assert_allclose(z.strides["stride_length_m"], yup.strides["stride_length_m"], atol=1e-5)


def _markers_only(subject: Subject, key: str, manifest: Manifest, params: IngestParams) -> ProcessedTrial:
    """`key` as the subject's only trial, without angles or forces, processed (`process_trial`)."""
    spec = TrialSpec(id="walk", condition="free", markers=key)
    trial = load_trial(dataclasses.replace(subject, trials=(spec,)), spec, manifest)
    return process_trial(trial, subject.markerset, params)


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
