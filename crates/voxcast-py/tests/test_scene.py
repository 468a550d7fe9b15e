"""Scenes: the TOML of `voxcast render --scene`, fields by dotted key."""

import pytest

import voxcast as vc


def test_scene_round_trips_through_toml_and_keywords_set_fields(tmp_path):
    s = vc.Scene(tf="ct-bone", azimuth=30, size=(320, 200), method="adaptive+grouped", step=0.25)
    assert s["camera.azimuth"] == 30.0
    assert (s["render.width"], s["render.height"]) == (320, 200)
    assert s["render.method"] == "adaptive" and s["render.grouped"] is True
    assert s.method == "adaptive+grouped"
    assert s["transfer.tf"] == "ct-bone"
    text = s.to_toml()
    assert "azimuth = 30" in text
    assert vc.Scene.from_toml(text) == s
    s.to_toml(tmp_path / "s.toml")
    assert vc.Scene.from_toml(tmp_path / "s.toml") == s
    s["render.adaptive.tolerance"] = 0.05
    assert s["render.adaptive.tolerance"] == pytest.approx(0.05)
    assert s != vc.Scene.from_toml(text)
    c = s.copy()
    c["camera.zoom"] = 2
    assert s["camera.zoom"] == 1.0


def test_a_bad_value_is_refused_and_leaves_the_scene_unchanged():
    s = vc.Scene()
    before = s.to_dict()
    with pytest.raises(vc.VoxcastError, match="render.step"):
        s["render.step"] = -2
    with pytest.raises(vc.VoxcastError, match="unknown field"):
        s["render.stepp"] = 1
    with pytest.raises(vc.VoxcastError):
        s.set(**{"camera.azimuth": 10, "render.block_size": 1000})
    assert s.to_dict() == before
    with pytest.raises(KeyError):
        s["camera.nothing"]
    with pytest.raises(vc.VoxcastError, match="no such scene file"):
        vc.Scene.from_toml("missing.toml")
    with pytest.raises(vc.VoxcastError, match="line 2"):
        vc.Scene.from_toml("[camera]\nazimuth = 'north'\n")
