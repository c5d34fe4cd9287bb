from pathlib import Path

from lookfeel.data import read_labels


def _read(tmp_path: Path, text: str):
    p = tmp_path / "labels.csv"
    p.write_text(text, encoding="utf-8")
    return read_labels(p)


def test_optional_columns_extra_targets_and_empty_cells(tmp_path: Path):
    table, problems = _read(
        tmp_path,
        "\ufefffabric_id,cluster_k5,stiffness,roughness\nF0003,4,2.5,\n7,,NA,0.25\n",
    )
    assert problems == []
    assert table.columns == ("stiffness", "roughness")
    assert table.cluster_column == "cluster_k5"
    assert table.rows[3].values == {"stiffness": 2.5}
    assert table.rows[3].cluster == 4
    assert table.rows[7].values == {"roughness": 0.25}
    assert table.rows[7].cluster is None


def test_every_bad_row_is_reported_with_its_line(tmp_path: Path):
    table, problems = _read(
        tmp_path,
        "fabric_id,cluster8,density,paper_split\n"
        "1,0,0.5,train\n"
        "x9,0,0.5,train\n"
        "1,0,0.5,train\n"
        "2,1.5,heavy,validation\n"
        "3,0\n",
    )
    assert [(p.line, p.message) for p in problems] == [
        (3, "fabric_id 'x9' is not an integer id (e.g. 12 or F0012)"),
        (4, "fabric 1 appears again (first at line 2)"),
        (5, "column 'density': 'heavy' is not a number"),
        (5, "column 'cluster8': '1.5' is not a cluster number (0, 1, ...)"),
        (5, "column 'paper_split': 'validation' is not one of train, test, excluded"),
        (6, "2 cells but the header has 4"),
    ]
    assert sorted(table.rows) == [1, 2]
    assert table.rows[2].values == {} and table.rows[2].cluster is None


def test_header_is_required(tmp_path: Path):
    _, problems = _read(tmp_path, "1,2,0.5\n2,3,0.6\n")
    assert len(problems) == 1
    assert problems[0].line == 1
    assert problems[0].message.startswith("no 'fabric_id' or 'object' column in the header")
    _, problems = _read(tmp_path, "")
    assert [p.message for p in problems] == ["labels file is empty"]


def test_an_infinite_cell_is_not_finite_and_a_nan_cell_is_unknown(tmp_path: Path):
    """The reader's words for a number that is not finite (synth's labels check says the same,
    tests/test_synth.py); a plain "nan" is an empty cell, "+nan" a number that is not finite."""
    table, problems = _read(
        tmp_path, "fabric_id,density,stiffness\n1,inf,2\n2,-inf,2\n3,nan,2\n4,+nan,2\n5,1,2\n"
    )
    assert [(p.line, p.message) for p in problems] == [
        (2, "column 'density': 'inf' is not finite"),
        (3, "column 'density': '-inf' is not finite"),
        (5, "column 'density': '+nan' is not finite"),
    ]
    assert table.rows[3].values == {"stiffness": 2.0}  # nan: unknown, not a problem
    assert table.rows[5].values == {"density": 1.0, "stiffness": 2.0}
