import json
import pickle

import pytest
import yaml

from lookfeel.modality import (
    Modality,
    Pair,
    PressKind,
    parse_modalities,
    slot_modality,
    slot_names,
)


def test_modalities_are_strings_that_round_trip():
    assert Modality.DEPTH == "depth"
    assert json.loads(json.dumps({"m": Modality.TOUCH})) == {"m": "touch"}
    assert yaml.safe_load(yaml.safe_dump([Modality.COLOR.value])) == ["color"]
    assert PressKind("fold") is PressKind.FOLD


def test_parse_modalities_keeps_order_and_drops_repeats():
    assert parse_modalities("touch, depth,touch") == (Modality.TOUCH, Modality.DEPTH)
    with pytest.raises(ValueError, match="unknown modality 'colour'.*depth, color, touch"):
        parse_modalities("depth,colour")
    with pytest.raises(ValueError, match="no modality"):
        parse_modalities(" , ")


def test_slot_names_number_repeated_modalities():
    views = [Modality.DEPTH, Modality.TOUCH, Modality.DEPTH]
    assert slot_names(views) == ["depth", "touch", "depth.1"]
    assert [slot_modality(s) for s in slot_names(views)] == views


def test_pair_parses_formats_and_round_trips():
    p = Pair.parse("depth_to_touch")
    assert (p.query, p.gallery) == (Modality.DEPTH, Modality.TOUCH)
    assert str(p) == "depth_to_touch" and type(str(p)) is str
    assert p == Pair(Modality.DEPTH, Modality.TOUCH) == Pair("depth", "touch") == "depth_to_touch"
    assert Pair.parse(str(p)) == p and Pair.parse(p) is p
    assert f"{p}_top1" == "depth_to_touch_top1" and f"{p:<16}|" == "depth_to_touch  |"
    assert p.reverse() == "touch_to_depth" and not p.same and Pair.parse("color_to_color").same
    assert json.loads(json.dumps({p: [p]})) == {"depth_to_touch": ["depth_to_touch"]}
    assert {p: 1}["depth_to_touch"] == 1
    assert pickle.loads(pickle.dumps(p)).gallery is Modality.TOUCH
    assert Pair.every([Modality.DEPTH, Modality.TOUCH]) == [
        "depth_to_depth",
        "depth_to_touch",
        "touch_to_depth",
        "touch_to_touch",
    ]
    with pytest.raises(AttributeError, match="immutable"):
        p.query = Modality.COLOR  # type: ignore[misc]


@pytest.mark.parametrize(
    "bad", ["touch-depth", "touch_to_", "_to_depth", "touch_to_colour", "touch_to_depth_to_color"]
)
def test_pair_rejects_what_is_not_a_pair(bad):
    with pytest.raises(ValueError, match=f"'{bad}' is not a modality pair query_to_gallery"):
        Pair.parse(bad)
    with pytest.raises(ValueError, match="unknown modality 'smell'"):
        Pair("smell", Modality.DEPTH)


def test_modality_of_takes_a_member_or_its_name_and_refuses_any_other():
    from lookfeel.errors import LookfeelError
    from lookfeel.modality import ModalityError

    assert Modality.of("color") is Modality.COLOR and Modality.of(Modality.TOUCH) is Modality.TOUCH
    assert "of" not in Modality.__members__ and len(Modality) == 3
    for bad in ("colour", "Color", "", 3, None):
        with pytest.raises(
            ModalityError, match=r"unknown modality .*; expected one of: depth, color, touch"
        ):
            Modality.of(bad)  # type: ignore[arg-type]
    assert issubclass(ModalityError, LookfeelError)  # one line from the CLI, a ValueError
