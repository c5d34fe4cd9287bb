import json

import pytest
import yaml

from lookfeel.modality import Modality, PressKind, parse_modalities, slot_modality, slot_names


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
