"""The model TOML: lossless round trip and errors that name the key."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from physics.config import (
    Crack,
    Deviations,
    GearPairModel,
    ModelConfigError,
    Operating,
    Spall,
    model_from_dict,
    model_from_toml,
    model_to_toml,
)


def test_default_round_trip() -> None:
    model = GearPairModel()
    text = model_to_toml(model)
    assert "[geometry]" in text and "[[sensors]]" in text
    assert model_from_toml(text) == model


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=30, deadline=None)
@given(
    errors=st.lists(finite, min_size=20, max_size=20),
    depth=st.floats(min_value=0, max_value=100),
    speed=st.floats(min_value=1e-3, max_value=1e5),
    tooth=st.integers(min_value=1, max_value=20),
)
def test_round_trip_is_lossless(
    errors: list[float], depth: float, speed: float, tooth: int
) -> None:
    model = GearPairModel(
        dofs="torsional",
        operating=Operating(speed_rpm=speed, load_torque_nm=123.456789012345),
        deviations=Deviations(
            pinion_pitch_errors_um=errors,
            spalls=[Spall(tooth=tooth, depth_um=depth), Spall(wheel="gear", tooth=3)],
            cracks=[Crack(tooth=tooth, stiffness_loss_fraction=0.3)],
        ),
    )
    assert model_from_toml(model_to_toml(model)) == model


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"geometry": {"modul_mm": 3}}, "geometry.modul_mm"),
        ({"colour": 1}, "colour"),
        ({"geometry": {"pinion_teeth": 20.5}}, "geometry.pinion_teeth"),
        ({"mesh": {"damping_ratio": "high"}}, "mesh.damping_ratio"),
        ({"dofs": "eight"}, "dofs"),
        ({"deviations": {"pinion_pitch_errors_um": [1.0, 2.0]}}, "pinion_pitch_errors_um"),
        ({"deviations": {"spalls": [{"tooth": 99}]}}, "spalls[0].tooth"),
        ({"deviations": {"spalls": [{"depht_um": 9}]}}, "deviations.spalls[0].depht_um"),
        ({"deviations": {"cracks": [{"stiffness_loss_fraction": 1.5}]}}, "cracks[0]"),
        ({"operating": {"speed_rpm": 0}}, "operating.speed_rpm"),
        ({"sensors": []}, "sensors"),
        ({"acquisition": {"oversampling": 0}}, "acquisition.oversampling"),
        ({"tachometer": {"name": "acc"}}, "distinct"),
    ],
)
def test_errors_name_the_key(data: dict, message: str) -> None:
    with pytest.raises(ModelConfigError, match=message.replace("[", r"\[").replace("]", r"\]")):
        model_from_dict(data)


def test_invalid_toml_text() -> None:
    with pytest.raises(ModelConfigError, match="not valid TOML"):
        model_from_toml("geometry = [")


def test_missing_keys_take_defaults() -> None:
    model = model_from_toml("[operating]\nspeed_rpm = 1500\n")
    assert model.operating.speed_rpm == 1500.0
    assert model.geometry == GearPairModel().geometry
