from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.config import ConfigError, ModelConfig, RunConfig
from lookfeel.data import read_labels, scan
from lookfeel.train.loop import resolve_classes

from ._tiny import write_tiny_dataset


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


# ---- ranks: one rule for data info, data check, training's class heads ------------------------


def _ranked(root: Path, hardness_of_3: str) -> Path:
    """Four fabrics with images; labels.csv with ranks ``hardness`` (fabric 3's cell given)."""
    write_tiny_dataset(
        root, fabrics=4, drapes=1, fold_presses=1, flat_presses=0, frames=1, labels=False
    )
    (root / "labels.csv").write_text(
        f"fabric_id,hardness,material\n1,0,cloth\n2,2,metal\n3,{hardness_of_3},wood\n4,1,cloth\n",
        encoding="utf-8",
    )
    return root


def test_one_odd_rank_makes_the_column_numbers_in_every_command_and_is_named(
    tmp_path: Path, capsys
):
    """``1.5`` among ranks 0, 1, 2: `data info` showed no classes for the column while a class
    head learnt 1.5 as a class of its own. Now the column is numbers everywhere (no classes
    in info, a class head refused), and the reader warns naming the file, line, column, fabric
    and cell; with the cell corrected, it is ranks everywhere."""
    root = _ranked(tmp_path / "odd", "1.5")
    catalog = scan(root)
    assert catalog.label_columns == ("hardness",) and catalog.rank_columns == ()
    assert catalog.class_columns == ("material",)
    assert "hardness" not in catalog.summary()["classes"]
    warning = (
        f"{root / 'labels.csv'}:4: column 'hardness': fabric 3 has '1.5', where the column's "
        "other values are whole numbers 0-10 (0, 1, 2): the whole column is read as numbers, "
        "not ranks (no classes in `lookfeel data info`, no class head); correct the cell if "
        "it is a rank"
    )
    assert [str(p) for p in catalog.warnings] == [warning]

    assert main(["data", "info", str(root)]) == 0
    info = capsys.readouterr().out
    assert "\n    material   cloth:2 metal:1 wood:1\n" in info  # the rows of classes
    assert "\n    hardness " not in info
    assert "0 errors, 1 warning in names and headers (run `lookfeel data check`)" in info
    assert main(["data", "check", str(root), "--no-leakage"]) == 0
    assert f"WARNING  {warning}\n" in capsys.readouterr().out

    heads = RunConfig(model=ModelConfig(backbone="compact", class_heads=("hardness",)))
    with pytest.raises(
        ConfigError,
        match=r"^model.class_heads: column 'hardness' of labels.csv is numbers, not classes: "
        r"F0003 has 1.5, not a whole number 0-10 \(a rank\)",
    ):
        resolve_classes(catalog, heads)

    fixed = scan(_ranked(tmp_path / "fixed", "1"))
    assert fixed.rank_columns == ("hardness",) and fixed.warnings == ()
    assert fixed.summary()["classes"]["hardness"] == {"0": 1, "1": 2, "2": 1}
    assert resolve_classes(fixed, heads).model.classes == {"hardness": ("0", "1", "2")}


def test_half_ranks_and_measurements_are_numbers_without_a_warning(tmp_path: Path):
    """A column of 0 and 1 with a few 0.5 (two of 20 here), a measurement, and the paper's
    physical labels (GelFabric's stretchiness is 0, 0.5 or 1) are numbers, and no typo; a rank
    below 0 (or above 10) breaks a column of ranks as 1.5 does."""
    rows = "".join(
        f"{i},{0.5 if i % 7 == 0 else i % 2},{1.2 + i / 10},{0.5 if i == 3 else i % 2},"
        f"{i % 3 if i != 5 else -1}\n"
        for i in range(1, 21)
    )
    header = "fabric_id,softness,thickness,stretchiness,hardness\n"
    table, problems = _read(tmp_path, header + rows)
    assert table.columns == ("softness", "thickness", "stretchiness", "hardness")
    assert table.rank_columns == ()
    assert [(p.line, p.severity, p.message[:45]) for p in problems] == [
        (6, "warning", "column 'hardness': fabric 5 has '-1', where t")
    ]


# ---- a spreadsheet's other separators, and classes spelt two ways ---------------------------


@pytest.mark.parametrize(
    ("content", "why"),
    [
        (
            b"fabric_id;density;material\n1;0.5;wool\n2;0.7;silk\n3;0.2;wool\n4;0.9;silk\n",
            "separated by semicolons (;), not commas: lookfeel reads comma-separated files; "
            "save it as CSV with commas; no label was read",
        ),
        (
            b"fabric_id;density;material\n1;0,5;wool\n2;0,7;silk\n3;0,2;wool\n4;0,9;silk\n",
            "separated by semicolons (;), not commas: lookfeel reads comma-separated files; "
            "save it as CSV with commas and a full stop as the decimal mark (it has '0,5'); "
            "no label was read",
        ),
        (
            b"fabric_id\tdensity\tmaterial\n1\t0.5\twool\n2\t0.7\tsilk\n3\t0.2\twool\n4\t1\tx\n",
            "separated by tabs, not commas",
        ),
        (
            "fabric_id\tdensity\n1\t0.5\n2\t0.7\n3\t0.2\n4\t0.9\n".encode("utf-16"),
            'saved as UTF-16 text, separated by tabs (a spreadsheet\'s "Unicode text"): '
            'lookfeel reads UTF-8 files separated by commas; save it as "CSV UTF-8 (comma '
            'delimited)"; no label was read',
        ),
    ],
    ids=["semicolons", "decimal-commas", "tabs", "utf-16"],
)
def test_a_labels_file_with_another_separator_is_one_error_and_no_cascade(
    tmp_path: Path, content: bytes, why: str
):
    """A European spreadsheet's labels.csv was one error about the header and one more per
    fabric ("has no row in labels.csv"): now one line saying how to save it."""
    root = write_tiny_dataset(
        tmp_path / "t", fabrics=4, drapes=1, fold_presses=1, flat_presses=0, frames=1,
        labels=False,
    )  # fmt: skip
    (root / "labels.csv").write_bytes(content)
    catalog = scan(root)
    (error,) = catalog.errors
    assert (error.path, error.line) == (root / "labels.csv", 1)
    assert why in error.message
    assert catalog.label_columns == () and all(not f.labels for f in catalog.fabrics)


def test_classes_spelt_in_two_cases_are_a_warning_naming_both(tmp_path: Path):
    """``Cotton`` and ``cotton`` silently made two classes."""
    table, problems = _read(
        tmp_path,
        "fabric_id,material,weave\n1,cotton,plain\n2,Cotton ,plain\n3,wool,Plain\n4,COTTON,x\n",
    )
    assert table.text_columns == ("material", "weave")
    assert [(p.line, p.severity, p.message) for p in problems] == [
        (
            2,
            "warning",
            "column 'material': 'cotton' (fabric 1, line 2) and 'Cotton' (fabric 2, line 3) and "
            "'COTTON' (fabric 4, line 5) differ only in case or spacing, so they are 3 classes; "
            "write them alike if they are one",
        ),
        (
            2,
            "warning",
            "column 'weave': 'plain' (fabric 1, line 2) and 'Plain' (fabric 3, line 4) differ "
            "only in case or spacing, so they are 2 classes; write them alike if they are one",
        ),
    ]
    _, problems = _read(tmp_path, "fabric_id,material\n1,cotton\n2,wool\n3,cotton\n")
    assert problems == []


def test_an_unnamed_empty_column_is_ignored_with_a_warning_and_one_with_values_is_an_error(
    tmp_path: Path,
):
    """QA: a spreadsheet saves its empty last column as a comma ending every line
    (``object,hardness,material,``), and the unnamed column was an error that blocked every
    command. A column with no name and no value is now ignored with a warning; one that holds
    values stays an error, hinting at a trailing comma where it is the last column."""
    ignored = (
        "column 4 has no name and no value in any row (the header ends with a comma, as a "
        "spreadsheet saves an empty last column): ignored"
    )
    for text in (
        "object,hardness,material,\negg,2,food,\nfelt,1,wool,\n,,,\n",
        "object,hardness,material,\negg,2,food\nfelt,1,wool,\n",  # a row without the comma
    ):
        table, problems = _read(tmp_path, text)
        assert [(p.line, p.severity, p.message) for p in problems] == [(1, "warning", ignored)]
        assert table.columns == ("hardness",) and table.text_columns == ("material",)
        assert table.named["egg"].values == {"hardness": 2.0}
        assert table.named["felt"].text == {"hardness": "1", "material": "wool"}
    table, problems = _read(tmp_path, "object,,hardness,,\negg,,2,,\nfelt,, 1\n")
    assert [(p.line, p.severity, p.message) for p in problems] == [
        (
            1,
            "warning",
            "columns 2, 4, 5 have no name and no value in any row (the header ends with a "
            "comma, as a spreadsheet saves an empty last column): ignored",
        )
    ]
    assert table.named["felt"].values == {"hardness": 1.0}
    # a row of another length is an error against the header as written
    _, problems = _read(tmp_path, "object,,hardness\negg,,2\nfelt,1\n")
    assert [(p.line, p.severity, p.message) for p in problems] == [
        (1, "warning", "column 2 has no name and no value in any row: ignored"),
        (3, "error", "2 cells but the header has 3"),
    ]
    # values under no name: an error, the other columns read
    table, problems = _read(tmp_path, "object,hardness,\negg,2,soft\nfelt,1,\n")
    assert [(p.line, p.severity, p.message) for p in problems] == [
        (
            1,
            "error",
            "column 3 has no name in the header (a trailing comma?) but holds values ('soft' at "
            "line 2): name it, or delete the column",
        )
    ]
    assert table.columns == ("hardness",) and table.named["felt"].values == {"hardness": 1.0}
    _, problems = _read(tmp_path, "object,,hardness\negg,x,2\n")
    assert [p.message for p in problems] == [
        "column 2 has no name in the header but holds values ('x' at line 2): name it, or "
        "delete the column"
    ]
    # a row with a comma too many
    _, problems = _read(tmp_path, "object,hardness\negg,2,\nfelt,1,x\n")
    assert [(p.line, p.message) for p in problems] == [
        (2, "3 cells but the header has 2 (a trailing comma?)"),
        (3, "3 cells but the header has 2"),
    ]


def test_data_check_warns_of_an_ignored_empty_column_and_passes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    root = write_tiny_dataset(
        tmp_path / "t", fabrics=3, drapes=1, fold_presses=1, flat_presses=0, frames=1,
        labels=False,
    )  # fmt: skip
    (root / "labels.csv").write_text("fabric_id,stiffness,\n1,2,\n2,3,\n3,1,\n", encoding="utf-8")
    assert main(["data", "check", str(root), "--no-leakage"]) == 0
    out = capsys.readouterr().out
    assert f"WARNING  {root / 'labels.csv'}:1: column 3 has no name and no value in any row" in out
    assert scan(root).fabric(2).labels == {"stiffness": 3.0}


@pytest.mark.parametrize(
    "content, why",
    [
        (
            b"Object,hardness\nsponge,0\ncork,1\n",
            "no 'fabric_id' or 'object' column in the header (first line); found: Object, "
            "hardness (names are case-sensitive: write 'object')",
        ),
        (b"name,hardness\nsponge,0\ncork,1\n", "found: name, hardness"),
        (b"", "labels file is empty"),
        ("object,hardness\nm\xe9tal,0\n".encode("latin-1"), "not a text CSV in UTF-8"),
    ],
    ids=["capitalised", "no-key", "empty", "latin1"],
)
def test_a_labels_file_without_a_key_column_is_one_error_and_no_cascade(
    tmp_path: Path, content: bytes, why: str
):
    """QA: a header of ``Object`` was refused clearly, and then every object was also "has no
    row in labels.csv": nothing of the file could be read, so those said nothing more."""
    from ._tiny import write_recordings

    root = write_recordings(tmp_path / "rec", {"sponge": 1, "cork": 2}, "")
    (root / "labels.csv").write_bytes(content)
    (error,) = scan(root).errors
    assert error.path == root / "labels.csv" and why in error.message


# ---- numbers as a spreadsheet writes them, and words read as unknown --------------------------


def test_a_column_of_decimal_commas_is_numeric_and_one_error_saying_what_to_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: quoted ``"0,7"`` cells (a European spreadsheet's decimal comma) made thickness_mm a
    text column: `data info` listed it under text labels, `data check` said nothing, and
    training said only "no class head for thickness_mm". One ``0,5`` among numbers was an
    error, though. Now the column is numeric either way, with one error naming the file, the
    column, a cell and what to write; the cells are unknown until then."""
    root = write_tiny_dataset(
        tmp_path / "t", fabrics=4, drapes=1, fold_presses=1, flat_presses=0, frames=1,
        labels=False,
    )  # fmt: skip
    (root / "labels.csv").write_text(
        'fabric_id,thickness_mm,material\n1,"0,7",cotton\n2,"0,5",wool\n3,"1,2",cotton\n'
        "4,0.9,wool\n",
        encoding="utf-8",
    )
    catalog = scan(root)
    assert catalog.label_columns == ("thickness_mm",)
    assert catalog.text_columns == ("material",)
    error = (
        f"{root / 'labels.csv'}:2: column 'thickness_mm': '0,7' is not a number (a comma as "
        "the decimal mark); 2 more of its cells are written so (line 3, 4): write 0.7, a full "
        "stop as the decimal mark; until then they are read as unknown"
    )
    assert [str(p) for p in catalog.errors] == [error]
    assert catalog.fabric(1).labels == {} and catalog.fabric(4).labels == {"thickness_mm": 0.9}
    assert main(["data", "info", str(root)]) == 0
    info = capsys.readouterr().out
    assert "text labels  material\n" in info and "labels       thickness_mm;" in info
    assert main(["data", "check", str(root), "--no-leakage"]) == 1
    assert f"ERROR    {error}\n" in capsys.readouterr().out

    # A single one among numbers: the same words.
    _, problems = _read(tmp_path, 'fabric_id,density\n1,0.2\n2,"0,5"\n3,0.4\n')
    assert [(p.line, p.message) for p in problems] == [
        (
            3,
            "column 'density': '0,5' is not a number (a comma as the decimal mark): write 0.5, "
            "a full stop as the decimal mark; until then it is read as unknown",
        )
    ]


def test_numbers_with_a_unit_or_grouped_digits_are_one_error_per_column_and_way(tmp_path: Path):
    """``0.7 mm`` (a unit) made a column of classes too; ``1_000`` was read as 1000 (Python's
    float takes underscores; no spreadsheet writes them) and ``1 000`` was a word. Words stay
    words: a column of names, or of pencil grades (``2B``), is text, with no error."""
    table, problems = _read(
        tmp_path,
        "fabric_id,thickness_mm,weight,stretch,count\n"
        "1,0.7 mm,120gsm,5 %,1_000\n"
        "2,0.5mm,90 gsm,7%,2 000\n"
        '3,"0,9 mm",100,3,"1,500"\n'
        "4,1.1,80,4,12\n",
    )
    assert table.columns == ("thickness_mm", "weight", "stretch", "count")
    assert table.text_columns == ()
    assert [(p.line, p.message) for p in problems] == [
        (
            2,
            "column 'thickness_mm': '0.7 mm' is not a number (a unit, mm); 2 more of its cells "
            "are written so (line 3, 4): write 0.7 (the column's name gives the unit); until "
            "then they are read as unknown",
        ),
        (
            2,
            "column 'weight': '120gsm' is not a number (a unit, gsm); 1 more of its cells is "
            "written so (line 3): write 120 and give the unit in the column's name "
            "(weight_gsm); until then they are read as unknown",
        ),
        (
            2,
            "column 'stretch': '5 %' is not a number (a unit, %); 1 more of its cells is written "
            "so (line 3): write 5 and give the unit in the column's name; until then they are "
            "read as unknown",
        ),
        (
            2,
            "column 'count': '1_000' is not a number (its digits grouped by '_'); 1 more of its "
            "cells is written so (line 3): write 1000, its digits together; until then they are "
            "read as unknown",
        ),
        (
            4,
            "column 'count': '1,500' is not a number (a comma as the decimal mark or thousands "
            "separator): write 1.500 or 1500, a full stop as the decimal mark; until then it is "
            "read as unknown",
        ),
    ]
    assert table.rows[1].values == {}
    assert table.rows[4].values == {"thickness_mm": 1.1, "weight": 80, "stretch": 4, "count": 12}
    assert table.rows[1].text["count"] == "1_000"  # kept as written

    table, problems = _read(
        tmp_path,
        "fabric_id,material,grade,note\n1,cotton,2B,2 mm thick\n2,wool,HB,soft\n"
        "3,silk,4H,3 layers\n",
    )
    assert problems == []
    assert table.text_columns == ("material", "grade", "note") and table.columns == ()


def test_none_in_a_text_column_is_unknown_with_a_warning_naming_the_column(tmp_path: Path):
    """``none``, ``NA``, ``null`` ... are unknown, as pandas reads them, so a class named
    "none" (a coating of none) vanished without a word. It is still unknown (labels.csv files
    write ``none`` for unknown too), and the reader says so per text column; ``NA`` and the
    other spellings that mean nothing else say nothing, nor does ``none`` in a numeric column."""
    table, problems = _read(
        tmp_path,
        "object,coating,finish,hardness\negg,None,NA,1\nfelt,wax,matt,none\nball,none,n/a,2\n"
        "cup,wax,gloss,\n",
    )
    assert table.text_columns == ("coating", "finish")
    assert "coating" not in table.named["egg"].text and "finish" not in table.named["ball"].text
    assert [(p.line, p.severity, p.message) for p in problems] == [
        (
            2,
            "warning",
            "column 'coating': 'None' (2 rows) is read as unknown, as an empty cell, NA and N/A "
            "are; if it is a class, write it as another word (such as 'no_coating'), else leave "
            "its cells empty",
        )
    ]
