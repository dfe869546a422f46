"""The scale stage's model.json lists each static marker left out of the model (issue 34 case 4):
its distance to the nearest bone and why."""

from __future__ import annotations

from types import SimpleNamespace

from pipeline.stages.scale import markers_left_out


def test_each_marker_left_out_is_listed_with_its_distance_and_reason():
    body = SimpleNamespace(markers_left_out={"RELB": 0.22134, "LW1": 0.19})
    listed = markers_left_out(body, 0.17)
    assert list(listed) == ["LW1", "RELB"]
    assert listed["RELB"]["distance_m"] == 0.2213
    assert "22.1 cm from the nearest bone" in listed["RELB"]["reason"]
    assert "marker_bone_distance_max_m: 0.17 m" in listed["RELB"]["reason"]
    assert markers_left_out(SimpleNamespace(markers_left_out={}), 0.17) == {}
