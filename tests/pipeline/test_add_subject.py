"""add-subject registers a subject from real files into a temp copy of the registry (a scratch copy:
new files keep file:// origins) or into a temp DVC repository (new files tracked with DVC; without
git, see test_add_subject_dvc.py for clones)."""

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from ingest.canonical import load_trial
from ingest.errors import IngestError, ManifestError, SubjectError
from ingest.manifest import Manifest
from ingest.subject import load_subject
from pipeline.cli import main
from pipeline.commands.add_subject import NewTrial, Registry, add_subject

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("GAITLOOP_MIRROR", ROOT.parent / "shared" / "data"))
OC = DATA / "opencap_labval_subject4"


@pytest.fixture
def registry(tmp_path) -> Registry:
    """Copies of the subject files, params.yaml and manifest; the repo's stay untouched."""
    shutil.copytree(ROOT / "data" / "subjects", tmp_path / "subjects")
    shutil.copy(ROOT / "params.yaml", tmp_path / "params.yaml")
    shutil.copy(ROOT / "data" / "sources.yaml", tmp_path / "sources.yaml")
    return Registry(
        subjects_dir=tmp_path / "subjects",
        params_path=tmp_path / "params.yaml",
        manifest_path=tmp_path / "sources.yaml",
        mirror=DATA,
    )


def toe_in_trials() -> list[NewTrial]:
    return [
        NewTrial.parse(
            f"toe_in={OC}/MarkerData/walkingTI{i}.trc,{OC}/IK/walkingTI{i}_ik.mot,"
            f"{OC}/ID/walkingTI{i}_grf.mot"
        )
        for i in (1, 2)
    ]


def free_and_toe_in_trials() -> list[NewTrial]:
    """Free walking is needed: the simulated human's reference motion is built from it."""
    free = NewTrial.parse(
        f"free={OC}/MarkerData/walking1.trc,{OC}/IK/walking1_ik.mot,{OC}/ID/walking1_grf.mot"
    )
    return [free, *toe_in_trials()]


def snapshot(reg: Registry) -> dict:
    return {p: p.read_bytes() for p in (reg.params_path, reg.manifest_path, *reg.subjects_dir.glob("*"))}


def test_registers_mirror_files_through_their_manifest_entries(registry):
    params_before = registry.params_path.read_text()
    manifest_before = registry.manifest_path.read_text()
    path = add_subject(
        "oc4toein",
        1.68,
        62.6,
        OC / "MarkerData" / "static1.trc",
        free_and_toe_in_trials(),
        up_axis="y",
        registry=registry,
    )
    subject = load_subject("oc4toein", registry.subjects_dir)
    assert path == registry.subjects_dir / "oc4toein.yaml"
    assert subject.conditions == ("free", "toe_in")
    assert [t.id for t in subject.trials] == ["walking1", "walkingTI1", "walkingTI2"]
    assert subject.trials[1].markers == "opencap_labval_subject4/MarkerData/walkingTI1.trc"  # existing key
    assert subject.trials[2].grf == "opencap_labval_subject4/ID/walkingTI2_grf.mot"
    assert subject.static.markers == "opencap_labval_subject4/MarkerData/static1.trc"
    assert subject.markerset == load_subject("opencap4").markerset  # found by fitting the file
    params = yaml.safe_load(registry.params_path.read_text())
    before = yaml.safe_load(params_before)
    assert params["subjects"] == [*before["subjects"], "oc4toein"]
    assert params["transfer"]["subjects"] == [*before["transfer"]["subjects"], "oc4toein"]  # gets a policy
    new_params = registry.params_path.read_text()
    assert new_params.replace("  - oc4toein\n", "").replace(", oc4toein]", "]").replace("[oc4toein]", "[]") \
        == params_before  # comments and order kept
    assert registry.manifest_path.read_text() == manifest_before  # nothing new to list
    trial = load_trial(subject, subject.trials[0], Manifest.load(registry.manifest_path, mirror=DATA))
    assert trial.plates is not None and trial.angles


def test_files_outside_the_manifest_get_file_origins_in_a_scratch_registry(registry, tmp_path):
    outside = tmp_path / "lab"
    outside.mkdir()
    for name in ("walking2.trc", "static1.trc"):
        shutil.copy(OC / "MarkerData" / name, outside / name)
    (outside / "walking2.trc").write_text((outside / "walking2.trc").read_text() + "\n")  # new content
    add_subject(
        "newlab",
        1.70,
        65.0,
        outside / "static1.trc",
        [NewTrial("free", outside / "walking2.trc")],
        markerset="opencap_labval",
        up_axis="y",
        dataset="lab",
        policy=False,
        registry=registry,
    )
    assert "newlab" not in yaml.safe_load(registry.params_path.read_text())["transfer"]["subjects"]  # replay
    subject = load_subject("newlab", registry.subjects_dir)
    key = subject.trials[0].markers
    assert key == "local/newlab/walking2.trc"
    assert subject.static.markers == "opencap_labval_subject4/MarkerData/static1.trc"  # same sha256
    entry = yaml.safe_load(registry.manifest_path.read_text())["files"][key]
    assert entry["url"] == (outside / "walking2.trc").as_uri() and len(entry["sha256"]) == 64
    manifest = Manifest.load(registry.manifest_path, mirror=DATA, cache=tmp_path / "raw")
    resolved = manifest.resolve(key)  # copied into the cache via file://, hash checked
    assert (
        resolved == tmp_path / "raw" / key
        and resolved.read_bytes() == (outside / "walking2.trc").read_bytes()
    )


def test_refusals_leave_the_registry_unchanged(registry, tmp_path):
    before = snapshot(registry)
    static = OC / "MarkerData" / "static1.trc"
    with pytest.raises(SubjectError, match="subject 'opencap4' is already registered"):
        add_subject("opencap4", 1.68, 62.6, static, free_and_toe_in_trials(), up_axis="y", registry=registry)
    with pytest.raises(IngestError, match="markers file not found"):
        add_subject(
            "x1",
            1.68,
            62.6,
            static,
            [NewTrial("free", tmp_path / "missing.trc")],
            up_axis="y",
            registry=registry,
        )
    garbage = tmp_path / "garbage.trc"
    garbage.write_text("PathFileType\t4\nnot\ta\ntrc\nfile\nat all\n1\t2\n3\t4\n")
    with pytest.raises(IngestError, match="unreadable markers file: not a TRC file"):
        add_subject("x1", 1.68, 62.6, static, [NewTrial("free", garbage)], up_axis="y", registry=registry)
    with pytest.raises(IngestError, match="cannot be ingested as subject 'x1'.*up_axis are wrong"):
        add_subject("x1", 1.68, 62.6, static, free_and_toe_in_trials()[:1], up_axis="z", registry=registry)
    with pytest.raises(SubjectError, match=r"no trial with condition in \['free'\]"):
        add_subject("x1", 1.68, 62.6, static, toe_in_trials(), up_axis="y", registry=registry)
    with pytest.raises(SubjectError, match="subject id must be"):
        add_subject("Bad Id", 1.68, 62.6, static, free_and_toe_in_trials(), registry=registry)
    assert snapshot(registry) == before
    text = registry.params_path.read_text()  # a block-style transfer.subjects: said, nothing written
    registry.params_path.write_text(text.replace("\n  subjects: []", "\n  subjects:\n    - lenhart2015", 1))
    before = snapshot(registry)
    with pytest.raises(SubjectError, match=r"params\.yaml.*no flow list 'subjects: \[\.\.\.\]' in the "
                       "top-level 'transfer:' block"):
        add_subject("x1", 1.68, 62.6, static, free_and_toe_in_trials(), up_axis="y", registry=registry)
    assert snapshot(registry) == before


def test_cli_add_subject_refuses_duplicate_with_one_line(registry, capsys):
    code = main(
        [
            "--params",
            str(registry.params_path),
            "add-subject",
            "camargo",
            "--height-m",
            "1.8",
            "--mass-kg",
            "75",
            "--static",
            str(OC / "MarkerData" / "static1.trc"),
            "--trial",
            f"free={OC}/MarkerData/walking1.trc",
        ]
    )
    assert code == 2
    assert "already registered" in capsys.readouterr().err


needs_dvc = pytest.mark.skipif(importlib.util.find_spec("dvc") is None, reason="DVC is not installed")


@pytest.fixture
def dvc_repo(tmp_path) -> Registry:
    """A DVC repository (no git) holding copies of the registry files: new files are tracked there."""
    root = tmp_path / "repo"
    (root / "data").mkdir(parents=True)
    for name in ("subjects", "markersets"):
        shutil.copytree(ROOT / "data" / name, root / "data" / name)
    shutil.copy(ROOT / "params.yaml", root / "params.yaml")
    shutil.copy(ROOT / "data" / "sources.yaml", root / "data" / "sources.yaml")
    env = {**os.environ, "DVC_NO_ANALYTICS": "1"}
    subprocess.run([sys.executable, "-m", "dvc", "init", "--no-scm", "-q"], cwd=root, env=env, check=True)
    subprocess.run([sys.executable, "-m", "dvc", "config", "core.analytics", "false"], cwd=root, env=env,
                   check=True)
    return Registry.of_repo(root, mirror=DATA)


def lab_files(folder: Path) -> tuple[Path, Path]:
    """A new walk (opencap4's walking2 with another header: a file the manifest does not know) and an
    exact copy of the static trial (listed: reuses its entry)."""
    folder.mkdir()
    walk, static = folder / "lab_walk.trc", folder / "lab_static.trc"
    lines = (OC / "MarkerData" / "walking2.trc").read_text().splitlines(keepends=True)
    walk.write_text("PathFileType\t4\t(X/Y/Z)\tlab_walk.trc\n" + "".join(lines[1:]))
    shutil.copy(OC / "MarkerData" / "static1.trc", static)
    return walk, static


def registry_files(reg: Registry) -> dict:
    return {p: p.read_bytes() for p in (reg.params_path, reg.manifest_path, *reg.subjects_dir.glob("*"))}


@needs_dvc
def test_new_files_are_tracked_with_dvc_under_repo_relative_paths(dvc_repo, tmp_path):
    walk, static = lab_files(tmp_path / "lab")
    add_subject("lab1", 1.70, 65.0, static, [NewTrial("free", walk)], markerset="opencap_labval",
                up_axis="y", dataset="lab", registry=dvc_repo)
    root = dvc_repo.root
    subject = load_subject("lab1", dvc_repo.subjects_dir)
    key = subject.trials[0].markers
    assert key == "local/lab1/lab_walk.trc"
    assert subject.static.markers == "opencap_labval_subject4/MarkerData/static1.trc"  # same sha256
    entry = yaml.safe_load(dvc_repo.manifest_path.read_text())["files"][key]
    assert entry["url"] == "dvc:data/raw/lab1/lab_walk.trc" and entry["path"] == "data/raw/lab1/lab_walk.trc"
    copy = root / "data" / "raw" / "lab1" / "lab_walk.trc"
    assert copy.read_bytes() == walk.read_bytes()
    dvc_file = yaml.safe_load((root / "data" / "raw" / "lab1" / "lab_walk.trc.dvc").read_text())
    assert dvc_file["outs"][0]["path"] == "lab_walk.trc"
    for path in (dvc_repo.manifest_path, subject.path, copy.with_name("lab_walk.trc.dvc")):
        text = path.read_text()
        assert str(tmp_path) not in text and "file://" not in text, path
    manifest = Manifest.load(dvc_repo.manifest_path, mirror=DATA, cache=tmp_path / "cache", root=root)
    assert manifest.resolve(key) == copy  # the DVC-tracked copy, hash checked
    trial = load_trial(subject, subject.trials[0], manifest)
    assert trial.time_s.size > 0
    copy.unlink()  # not checked out (a clone before `dvc pull`): says how to get it
    with pytest.raises(ManifestError, match="dvc pull data/raw/lab1/lab_walk.trc.dvc"):
        Manifest.load(dvc_repo.manifest_path, mirror=DATA, cache=tmp_path / "cache", root=root).resolve(key)


@needs_dvc
def test_origin_url_is_the_new_files_origin(dvc_repo, tmp_path):
    walk, static = lab_files(tmp_path / "lab")
    with pytest.raises(SubjectError, match="origin must be an http"):
        add_subject("lab2", 1.70, 65.0, static, [NewTrial("free", walk)], markerset="opencap_labval",
                    up_axis="y", origin=str(tmp_path), registry=dvc_repo)
    add_subject("lab2", 1.70, 65.0, static, [NewTrial("free", walk)], markerset="opencap_labval",
                up_axis="y", origin="https://example.org/lab/", registry=dvc_repo)
    entry = yaml.safe_load(dvc_repo.manifest_path.read_text())["files"]["local/lab2/lab_walk.trc"]
    assert entry["url"] == "https://example.org/lab/lab_walk.trc"
    assert entry["path"] == "data/raw/lab2/lab_walk.trc"


@needs_dvc
def test_dvc_refusals_and_failures_write_nothing(dvc_repo, tmp_path):
    walk, static = lab_files(tmp_path / "lab")
    before = registry_files(dvc_repo)
    raw = dvc_repo.root / "data" / "raw"
    args = (1.70, 65.0, static, [NewTrial("free", walk)])
    outside = tmp_path / "my_set.yaml"
    shutil.copy(ROOT / "data" / "markersets" / "opencap_labval.yaml", outside)
    with pytest.raises(SubjectError, match="marker set file is outside the repository"):
        add_subject("lab3", *args, markerset=str(outside), up_axis="y", registry=dvc_repo)
    (raw / "lab3").mkdir(parents=True)
    with pytest.raises(SubjectError, match="raw folder of subject 'lab3' already exists"):
        add_subject("lab3", *args, markerset="opencap_labval", up_axis="y", registry=dvc_repo)
    (raw / "lab3").rmdir()
    config = dvc_repo.root / ".dvc" / "config"
    good = config.read_text()
    config.write_text("[core\nbroken")  # `dvc add` fails after the copies were made: they are removed
    with pytest.raises(SubjectError, match="`dvc add` failed"):
        add_subject("lab3", *args, markerset="opencap_labval", up_axis="y", registry=dvc_repo)
    assert not (raw / "lab3").exists()
    config.write_text(good)
    shutil.rmtree(dvc_repo.root / ".dvc")
    with pytest.raises(SubjectError, match="not a DVC repository"):
        add_subject("lab3", *args, markerset="opencap_labval", up_axis="y", registry=dvc_repo)
    assert registry_files(dvc_repo) == before and not (raw / "lab3").exists()
