"""The package's shape: no import cycle between its modules, and every module says what it is for.

Read from the source (``ast``), not by importing: every ``import`` counts, including those inside
functions and under ``TYPE_CHECKING``, because a cycle through a function-level import is still
two modules that cannot be understood, tested or moved one without the other.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import lookfeel

PACKAGE = Path(lookfeel.__file__).parent

KNOWN_CYCLES: tuple[frozenset[str], ...] = ()
"""Cycles this branch tolerates, each as the set of its modules. Keep it empty."""


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imported(name: str, path: Path, known: set[str]) -> set[str]:
    """The lookfeel modules that the module ``name`` (at ``path``) imports, anywhere in it.

    ``from a.b import c`` is an edge to ``a.b.c`` where that is a module, else to ``a.b``.
    Relative imports are resolved against the module's package.
    """
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            for alias in node.names:
                sub = f"{module}.{alias.name}"
                out.add(sub if sub in known else module)
    return {m for m in out if m in known and m != name}


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    known = set(modules)
    return {name: _imported(name, path, known) for name, path in modules.items()}


def _tangles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan): each holds a cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


def _a_cycle(graph: dict[str, set[str]], component: set[str]) -> list[str]:
    """A path through ``component`` that comes back to where it started, to print."""
    path = [min(component)]
    while True:
        nxt = min(w for w in graph[path[-1]] if w in component)
        if nxt in path:
            return [*path[path.index(nxt) :], nxt]
        path.append(nxt)


def test_the_graph_sees_every_kind_of_import():
    graph = _graph()
    assert len(graph) > 90
    assert "lookfeel.data.summary" in graph["lookfeel.demo"]  # module-level, absolute
    assert "lookfeel.demo" in graph["lookfeel.cli.demo"]  # inside a function
    assert "lookfeel.evaluate.core" in graph["lookfeel.evaluate.from_checkpoint"]  # relative
    assert "lookfeel.cli.data" in graph["lookfeel.cli"]  # `from package import module`


def test_the_cycle_finder_finds_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "e"}, "d": {"a"}, "e": set(), "f": {"f"}}
    assert _tangles(graph) == [{"a", "b", "c"}]
    assert _a_cycle(graph, {"a", "b", "c"}) == ["a", "b", "c", "a"]
    assert _tangles({"a": {"b"}, "b": set()}) == []
    graph = {"a": {"b"}, "b": {"c"}, "c": {"b"}}
    assert _a_cycle(graph, {"b", "c"}) == ["b", "c", "b"]


def test_no_import_cycle():
    graph = _graph()
    tangles = [t for t in _tangles(graph) if frozenset(t) not in KNOWN_CYCLES]
    assert not tangles, "import cycles:\n" + "\n".join(
        " -> ".join(_a_cycle(graph, t)) + (f" ({len(t)} modules tangled)" if len(t) > 2 else "")
        for t in tangles
    )


@pytest.mark.parametrize("name", sorted(_modules()))
def test_every_module_says_what_it_is_for(name: str):
    path = _modules()[name]
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    assert doc and len(doc.split()) >= 4, f"{path}: no module docstring saying what it is for"


def test_the_top_level_holds_what_a_python_user_starts_with():
    """QA: `lookfeel.__all__` lacked `RunConfig`, which `load_config` needs. It now holds the
    configs, the errors and `load_model`; each name there resolves, and ``import lookfeel``
    still imports no torch (the names that need it are imported on first use)."""
    code = (
        "import sys, lookfeel\n"
        "print('torch' in sys.modules)\n"
        "[getattr(lookfeel, n) for n in lookfeel.__all__]\n"
        "print('torch' in sys.modules)\n"
        "from lookfeel import RunConfig, load_config, load_model\n"
        "print(load_config(RunConfig, None).train.steps > 0, load_model.__module__)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split("\n")[:3] == ["False", "True", "True lookfeel.checkpoint"]
    assert {"RunConfig", "ModelConfig", "TrainConfig", "LookfeelError", "DeviceError"} <= set(
        lookfeel.__all__
    )
    with pytest.raises(AttributeError, match="module 'lookfeel' has no attribute 'nothing'"):
        lookfeel.nothing  # noqa: B018


def test_the_match_path_imports_no_probe_or_fitting_library():
    """Session 56: `lookfeel match` imported scikit-learn, scipy.stats and scipy.optimize (0.9 s
    of a 2.9 s start) through `lookfeel.metrics` and `lookfeel.index.calibrate`, for probes and
    fits that matching never runs. They are imported where those fit, so the modules ``match``
    runs (its command, the library, the matcher, `guess_modality`) import none of them."""
    code = (
        "import sys\n"
        "import lookfeel.cli.match, lookfeel.errors, lookfeel.index, lookfeel.predict\n"
        "from lookfeel.index import Library, Matcher, format_match\n"
        "heavy = ('sklearn', 'scipy.stats', 'scipy.optimize')\n"
        "print(sorted(m for m in heavy if m in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_the_top_level_holds_the_names_a_researcher_meets_first():
    """QA (session 57, F10): `Pair`, the type of every metric key, and `ModalityError`, which
    `lookfeel.Modality.of` raises, were missing from the top level; losses had no counterpart
    of `list_backbones`. The top level names where to register one's own."""
    from lookfeel.losses import list_losses
    from lookfeel.modality import ModalityError, Pair
    from lookfeel.models import list_backbones

    assert {"Pair", "ModalityError"} <= set(lookfeel.__all__)
    assert lookfeel.Pair is Pair and lookfeel.ModalityError is ModalityError
    with pytest.raises(lookfeel.ModalityError):
        lookfeel.Modality.of("smell")
    assert "contrastive" in list_losses() and "compact" in list_backbones()
    doc = lookfeel.__doc__ or ""
    for name in ("register_backbone", "register_loss", "list_losses", "list_backbones"):
        assert name in doc


def _declared(path: Path) -> set[str] | None:
    """The names a module's ``__all__ = [...]`` lists, or None when it has none."""
    for node in ast.parse(path.read_text(encoding="utf-8"), filename=str(path)).body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            return {ast.literal_eval(e) for e in node.value.elts}  # type: ignore[attr-defined]
    return None


def _undeclared_imports(
    modules: dict[str, Path] | None = None,
) -> dict[str, dict[str, set[str]]]:
    """Module -> name -> the modules that import it, for every ``from lookfeel.x.y import
    name`` (or relative ``from .y import name``) of a public name of a public module that the
    module's ``__all__`` leaves out. A name starting with ``_``, a submodule, and any name of a
    private module (``cli/_args.py``, ``metrics/_ranking.py``: internal by their file's name)
    need no declaration. ``modules`` (name -> file) defaults to lookfeel's own."""
    modules = _modules() if modules is None else modules
    out: dict[str, dict[str, set[str]]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            if module not in modules or module.rpartition(".")[2].startswith("_"):
                continue
            declared = _declared(modules[module]) or set()
            for alias in node.names:
                public = not alias.name.startswith("_") and alias.name != "*"
                submodule = f"{module}.{alias.name}" in modules
                if public and not submodule and alias.name not in declared:
                    out.setdefault(module, {}).setdefault(alias.name, set()).add(name)
    return out


def test_what_one_module_imports_from_another_is_in_its_all():
    """QA (session 57, F9): ``from lookfeel.train import train_step`` failed though
    ``train/loop.py``'s ``__all__`` listed it, and `lookfeel.evaluate.core`'s ``__all__`` left
    out `exact_protocol` and `keep_pick`, which `lookfeel.evaluate.controls` imports. A name
    one lookfeel module imports from another (a package's ``__init__`` included) is that
    module's public interface, so its ``__all__`` lists it. Private names (``_x``) and private
    modules (``_x.py``) are exempt: their leading ``_`` already says "internal, shared inside
    the package"."""
    found = {
        f"{module}.{n} (imported by {', '.join(sorted(users))})"
        for module, names in _undeclared_imports().items()
        for n, users in names.items()
    }
    assert not found, "declare in the module's __all__:\n" + "\n".join(sorted(found))
    import lookfeel.train
    from lookfeel.train import TrainRun, train_step
    from lookfeel.train.loop import __all__ as loop_all

    assert {"TrainRun", "train_step"} <= set(lookfeel.train.__all__)
    assert TrainRun.__module__ == train_step.__module__ == "lookfeel.train.loop"
    assert set(lookfeel.train.__all__) - {"FeatureTable", "TrainingDiverged"} - {
        "default_pairs",
        "validate",
    } <= set(loop_all)


def test_the_all_rule_sees_relative_imports_and_exempts_private_names(tmp_path):
    """The rule on a small package of its own: it finds an undeclared name imported
    absolutely and relatively, and from a module with no ``__all__`` at all; it passes a
    declared name, a private name, a submodule and any name of a private module."""
    files = {
        "pkg/__init__.py": "from . import a\n",
        "pkg/a.py": '__all__ = ["x"]\nx = y = z = _q = 1\n',
        "pkg/bare.py": "w = 1\n",
        "pkg/_priv.py": "v = 1\n",
        "pkg/b.py": (
            "from pkg.a import x, y\nfrom .a import _q, z\nfrom .bare import w\n"
            "from ._priv import v\nfrom . import a\n"
        ),
    }
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(exist_ok=True)
        (tmp_path / rel).write_text(text, encoding="utf-8")
    modules = {
        rel.removesuffix(".py").removesuffix("/__init__").replace("/", "."): tmp_path / rel
        for rel in files
    }
    assert _undeclared_imports(modules) == {
        "pkg.a": {"y": {"pkg.b"}, "z": {"pkg.b"}},
        "pkg.bare": {"w": {"pkg.b"}},
    }
