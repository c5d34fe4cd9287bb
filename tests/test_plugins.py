"""Plugins: a user's own module named in LOOKFEEL_PLUGINS, by ``lookfeel --plugin`` or by an
entry point registers its backbone and loss in this process and in the processes lookfeel
spawns (reproduce's workers)."""

from __future__ import annotations

import importlib.metadata
import os
import sys
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import ClassVar

import pytest
import yaml

from lookfeel import plugins
from lookfeel.cli import main
from lookfeel.config import ConfigError, LossConfig, ModelConfig, RunConfig, load_config
from lookfeel.config.model import backbone_names
from lookfeel.plugins import PluginError, PluginWarning, load_plugins

from ._registry import restored_registries

_ENTRY_POINTS = importlib.metadata.entry_points
"""The real look-up of installed entry points (the `plugin` fixture hides the installed ones)."""

TINY_CONFIG = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"

PLUGIN = '''\
"""A user's module: a backbone and a loss of their own (docs/ARCHITECTURE.md's example)."""
import torch
from torch import nn

from lookfeel.losses import FabricPairLoss, register_loss
from lookfeel.models import Backbone, register_backbone

CALLS = []


@register_backbone("{name}")
class TinyConv(Backbone):
    freeze_points = {{"none": 0, "to_conv": 1, "all": 2}}
    min_size = 8

    def _build(self, freeze, dropout, width):
        w = width or 16
        self.conv = nn.Sequential(nn.Conv2d(self.stem_channels, w, 3, 2, 1), nn.ReLU())
        self.pool = nn.Sequential(nn.AdaptiveAvgPool2d(1), nn.Flatten(1))
        self._set_stages([self.conv, self.pool], freeze or "none", embed_dim=w)


class MeanDistance(FabricPairLoss):
    loss_name = "the mean distance"

    def pair_term(self, ea, eb, fa, fb):
        return torch.cdist(ea, eb).mean()


register_loss("{name}_loss", lambda config: MeanDistance())


def setup():
    CALLS.append(1)
'''


@pytest.fixture
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[str], str]]:
    """``plugin(name)`` writes module ``name`` (registering backbone ``name`` and loss
    ``name_loss``) into a folder on sys.path and returns its name. LOOKFEEL_PLUGINS starts
    empty; afterwards the registries, sys.modules and `load_plugins`' memory are as before."""
    folder = tmp_path / "plugins"
    folder.mkdir()
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setenv("LOOKFEEL_PLUGINS", "")  # restored (or removed) after the test
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **kw: [])
    written: list[str] = []

    def write(name: str) -> str:
        (folder / f"{name}.py").write_text(PLUGIN.format(name=name), encoding="utf-8")
        written.append(name)
        return name

    plugins._reset()
    try:
        with restored_registries():
            yield write
    finally:
        plugins._reset()
        for name in written:
            sys.modules.pop(name, None)


def test_a_module_of_lookfeel_plugins_registers_its_backbone_and_loss(plugin, monkeypatch):
    name = plugin("lfplug_known")
    with pytest.raises(ConfigError) as e:
        ModelConfig(backbone=name)
    assert str(e.value) == (
        "model.backbone: 'lfplug_known' is not one of alexnet, compact, resnet18 (one of your "
        "own: import its module first, or name it in LOOKFEEL_PLUGINS or lookfeel --plugin, "
        "which lookfeel.plugins.load_plugins() imports)"
    )
    with pytest.raises(ConfigError, match=r"contrastive, infonce, triplet \(one of your own: im"):
        LossConfig(kind=f"{name}_loss")
    monkeypatch.setenv("LOOKFEEL_PLUGINS", f" ,{name} , ")  # spaces and empty entries ignored
    load_plugins()
    assert ModelConfig(backbone=name).backbone == name
    assert LossConfig(kind=f"{name}_loss").kind == f"{name}_loss"

    from lookfeel.models import create_backbone

    assert type(create_backbone(name)).__name__ == "TinyConv"


def test_the_config_loads_the_plugins_when_it_meets_an_unknown_name(plugin, monkeypatch):
    """QA: a script of one's own (``LOOKFEEL_PLUGINS=my_ext python -c "lookfeel.load_model(...)"``)
    was refused the backbone that LOOKFEEL_PLUGINS names: only `lookfeel.cli.main` loaded it."""
    name, other = plugin("lfplug_lazy"), plugin("lfplug_lazy_loss")
    monkeypatch.setenv("LOOKFEEL_PLUGINS", name)
    assert name not in sys.modules
    assert LossConfig(kind=f"{name}_loss").kind == f"{name}_loss"  # the loss alone, first
    assert name in sys.modules and name in backbone_names()
    config = load_config(RunConfig, overrides=[f"model.backbone={name}"])
    assert config.model.backbone == name
    # Added to the variable later (a script's os.environ): the next unknown name loads it.
    monkeypatch.setenv("LOOKFEEL_PLUGINS", f"{name},{other}")
    assert ModelConfig(backbone=other).backbone == other
    # A name no plugin registers says which plugins were loaded.
    with pytest.raises(ConfigError) as e:
        ModelConfig(backbone="lfplug_none")
    assert str(e.value).endswith(
        "(one of your own: import its module first, or name it in LOOKFEEL_PLUGINS or lookfeel "
        "--plugin; the plugins loaded (lfplug_lazy, lfplug_lazy_loss) register no such name)"
    )


def test_the_config_loads_entry_points_once_and_a_bad_plugin_is_its_one_line(
    plugin, tmp_path: Path, monkeypatch
):
    fn_name = plugin("lfplug_lazy_ep")
    _install(tmp_path / "plugins", "lab-ext", f"setup = {fn_name}:setup")
    asked: list[str] = []

    def entry_points(*, group: str) -> object:
        asked.append(group)
        return _ENTRY_POINTS(group=group)

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    assert ModelConfig(backbone=fn_name).backbone == fn_name  # "installed, it loads everywhere"
    for _ in range(2):
        with pytest.raises(ConfigError, match=r"entry point setup\) register no such name\)$"):
            ModelConfig(backbone="lfplug_none")
    assert asked == ["lookfeel.plugins"] and sys.modules[fn_name].CALLS == [1]
    # A plugin that cannot be imported: the same line as from `load_plugins`, not a config's.
    monkeypatch.setenv("LOOKFEEL_PLUGINS", "lfplug_nowhere")
    for load in (
        lambda: load_config(RunConfig, overrides=["model.backbone=lfplug_none"]),
        lambda: LossConfig(kind="lfplug_none"),
    ):
        with pytest.raises(PluginError) as e:
            load()
        assert str(e.value) == (
            "LOOKFEEL_PLUGINS: cannot import 'lfplug_nowhere' (No module named "
            "'lfplug_nowhere'); is its folder on PYTHONPATH?"
        )


def test_a_plugin_that_meets_an_unknown_name_while_loading_does_not_load_again(
    plugin, tmp_path: Path, monkeypatch
):
    name = plugin("lfplug_reentrant")
    path = tmp_path / "plugins" / f"{name}.py"
    path.write_text(
        path.read_text(encoding="utf-8")
        + "\n\ndef check():\n"
        + "    from lookfeel.config import ConfigError, ModelConfig\n"
        + "    try:\n"
        + "        ModelConfig(backbone='lfplug_none')\n"
        + "    except ConfigError:\n"
        + "        CALLS.append('refused')\n",
        encoding="utf-8",
    )
    _install(tmp_path / "plugins", "lab-ext", f"check = {name}:check")
    monkeypatch.setattr(importlib.metadata, "entry_points", _ENTRY_POINTS)
    load_plugins()  # without a guard: check -> load_plugins -> check ... RecursionError
    assert sys.modules[name].CALLS == ["refused"]


def test_load_plugins_imports_each_module_once(plugin, monkeypatch):
    first, second = plugin("lfplug_once_a"), plugin("lfplug_once_b")
    monkeypatch.setenv("LOOKFEEL_PLUGINS", first)
    load_plugins()
    assert first in sys.modules
    del sys.modules[first]
    load_plugins()  # done already: not imported again
    assert first not in sys.modules
    monkeypatch.setenv("LOOKFEEL_PLUGINS", f"{first},{second}")
    load_plugins()  # a module added since is imported
    assert first not in sys.modules and second in sys.modules
    assert second in backbone_names()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (
            "lfplug_nowhere",
            "LOOKFEEL_PLUGINS: cannot import 'lfplug_nowhere' (No module named 'lfplug_nowhere');"
            " is its folder on PYTHONPATH?",
        ),
        (
            "lfplug_nowhere.backbones",
            "LOOKFEEL_PLUGINS: cannot import 'lfplug_nowhere.backbones' (No module named "
            "'lfplug_nowhere'); is its folder on PYTHONPATH?",
        ),
        (
            "plugins/lfplug.py",
            "LOOKFEEL_PLUGINS: 'plugins/lfplug.py' is a file, not a module name: put its folder "
            "on PYTHONPATH and name the module (PYTHONPATH=plugins LOOKFEEL_PLUGINS=lfplug)",
        ),
        (
            "lab-ext",
            "LOOKFEEL_PLUGINS: 'lab-ext' is not a module name (e.g. my_ext or lab.backbones, not "
            "a file); put its folder on PYTHONPATH and name the module",
        ),
    ],
)
def test_a_module_that_cannot_be_imported_is_one_line(plugin, monkeypatch, value, message):
    monkeypatch.setenv("LOOKFEEL_PLUGINS", value)
    with pytest.raises(PluginError) as e:
        load_plugins()
    assert str(e.value) == message


def test_a_plugin_that_fails_is_named_with_its_line(plugin, tmp_path: Path, monkeypatch):
    name = plugin("lfplug_broken")
    path = tmp_path / "plugins" / f"{name}.py"
    path.write_text(
        "import os\n\nraise RuntimeError('no GPU here. Details follow')\n", encoding="utf-8"
    )
    monkeypatch.setenv("LOOKFEEL_PLUGINS", name)
    with pytest.raises(PluginError) as e:
        load_plugins()
    assert str(e.value) == (
        f"LOOKFEEL_PLUGINS: cannot import 'lfplug_broken' (RuntimeError: no GPU here, at {path}:3)"
    )


def test_the_plugin_option_trains_a_backbone_of_ones_own(
    plugin, tiny_dataset: Path, tmp_path: Path, monkeypatch, capsys
):
    name = plugin("lfplug_cli")
    out = tmp_path / "run"
    sets = [f"model.backbone={name}", f"loss.kind={name}_loss", "train.steps=1"]
    sets += ["train.val_every=0", "train.checkpoint_every=0", "train.views=[depth,touch]"]
    args = ["train", "--config", str(TINY_CONFIG), "--data", str(tiny_dataset), "--out", str(out)]
    with restored_registries():
        assert main(["--plugin", name, *args, *(x for s in sets for x in ("--set", s))]) == 0
    saved = yaml.safe_load((out / "config.yaml").read_text(encoding="utf-8"))
    assert (saved["model"]["backbone"], saved["loss"]["kind"]) == (name, f"{name}_loss")
    assert os.environ["LOOKFEEL_PLUGINS"] == name  # what worker processes inherit
    # A fresh script with the variable set loads the run's checkpoint: the plugin loads itself.
    plugins._reset()
    del sys.modules[name]
    assert name not in backbone_names()
    from lookfeel.checkpoint import load_model

    with restored_registries():
        loaded = load_model(out / "checkpoints" / "last.pt")
        assert type(loaded.model.branch("depth").backbone).__name__ == "TinyConv"
    # Where the plugin is not loaded, the error names the module the run was trained with.
    from lookfeel.checkpoint import CheckpointError

    plugins._reset()
    del sys.modules[name]
    monkeypatch.setenv("LOOKFEEL_PLUGINS", "")
    with pytest.raises(CheckpointError) as e:
        load_model(out / "checkpoints" / "last.pt")
    assert str(e.value).endswith(
        f"(the run was trained with the plugin module {name}: lookfeel --plugin {name}, with "
        "its folder on PYTHONPATH)"
    )
    assert "model.backbone: 'lfplug_cli' is not one of" in str(e.value)
    # So does resuming it (QA, session 57, F17: --resume named the unknown name, not the module).
    hint = (
        f" (the run was trained with the plugin module {name}: lookfeel --plugin {name}, with "
        "its folder on PYTHONPATH)"
    )
    capsys.readouterr()
    resume = ["train", "--resume", "--data", str(tiny_dataset), "--out", str(out)]
    assert main([*resume, "--set", "train.steps=2"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"lookfeel: {out / 'config.yaml'}: model.backbone: 'lfplug_cli' is not")
    assert err.endswith(f"{hint}\n") and err.count("\n") == 1
    from lookfeel.train import train

    given = load_config(RunConfig, TINY_CONFIG, ["train.steps=2", "train.views=[depth,touch]"])
    with pytest.raises(ConfigError) as e:
        train(given, tiny_dataset, out, resume=True)
    assert str(e.value).startswith(
        f"--resume (resume=True): {out / 'checkpoints' / 'last.pt'}: the run's config does not "
        "load: model.backbone: 'lfplug_cli' is not one of"
    )
    assert str(e.value).endswith(hint)
    # Installed as an entry point that now fails to import: the error names it and why.
    (tmp_path / "plugins" / f"{name}.py").write_text(
        "import lfplug_missing_dependency\n", encoding="utf-8"
    )
    plugins._reset()
    monkeypatch.setattr(plugins, "_entry_points", lambda: [_entry_point("cli", name)])
    warned = pytest.warns(PluginWarning, match="entry point 'cli'")
    with warned, pytest.raises(CheckpointError) as e:
        load_model(out / "checkpoints" / "last.pt")
    assert (
        "(one of your own: import its module first, or name it in LOOKFEEL_PLUGINS or lookfeel "
        "--plugin, which lookfeel.plugins.load_plugins() imports; entry point 'cli' = "
        "'lfplug_cli' did not load (ModuleNotFoundError: No module named "
        "'lfplug_missing_dependency')) (the run was trained with the plugin module lfplug_cli: "
        "lookfeel --plugin lfplug_cli, with its folder on PYTHONPATH)"
    ) in str(e.value)


_CLUSTER_AWARE = '''\
"""A user's module: a loss with a setting of its own that reads the cluster targets."""
from torch import nn

from lookfeel.losses import register_loss

SEEN = []


class ClusterAware(nn.Module):
    def __init__(self, alpha):
        super().__init__()
        self.alpha = alpha

    def forward(self, embeddings, y=None, fabric=None, cluster=None):
        SEEN.append({s: (fabric[s].tolist(), c.tolist()) for s, c in cluster.items()})
        a, b = embeddings.values()
        return {"pull_loss": self.alpha * (a - b).pow(2).sum(1).mean()}


register_loss("clusteraware", lambda config: ClusterAware(config.options["alpha"]))
'''


def test_a_loss_of_one_s_own_trains_with_its_options_and_the_batch_s_targets(
    plugin, tiny_dataset: Path, tmp_path: Path
):
    """QA (session 57, F5): a loss of one's own saw only embeddings and fabric ids, and could
    have no setting of its own. Trained through the command line, it is built from
    ``loss.options`` (recorded in the run's config) and given the batch's cluster targets,
    though the model has no cluster head (tiny.yaml has none)."""
    name = plugin("lfplug_cluster")
    (tmp_path / "plugins" / f"{name}.py").write_text(_CLUSTER_AWARE, encoding="utf-8")
    out = tmp_path / "run"
    sets = ["loss.kind=clusteraware", "loss.options.alpha=0.5", "train.steps=2"]
    sets += ["train.val_every=0", "train.checkpoint_every=0", "train.views=[depth,touch]"]
    args = ["train", "--config", str(TINY_CONFIG), "--data", str(tiny_dataset), "--out", str(out)]
    assert main(["--plugin", name, *args, *(x for s in sets for x in ("--set", s))]) == 0
    seen = sys.modules[name].SEEN
    assert len(seen) == 2 and all(set(step) == {"depth", "touch"} for step in seen)
    # Each fabric's cluster is its labels.csv cluster8 (tests/_tiny.py: fabric f's is (f-1) % 3).
    for step in seen:
        for ids, clusters in step.values():
            assert len(ids) == 8 and clusters == [(f - 1) % 3 for f in ids]
    saved = yaml.safe_load((out / "config.yaml").read_text(encoding="utf-8"))
    assert saved["loss"]["options"] == {"alpha": 0.5}
    lines = [
        yaml.safe_load(line)
        for line in (out / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    ]
    logged = [line for line in lines if "loss" in line][-1]
    assert set(logged) >= {"pull_loss", "loss"} and "cluster_loss" not in logged


def test_a_bad_plugin_option_prints_one_line_and_exits_1(
    plugin, tmp_path: Path, monkeypatch, capsys
):
    good = plugin("lfplug_good")
    monkeypatch.setenv("LOOKFEEL_PLUGINS", good)
    args = ["--plugin", "lfplug_nowhere", "--plugin", good, "data", "info", str(tmp_path)]
    assert main(args) == 1
    assert capsys.readouterr().err == (
        "lookfeel: --plugin: cannot import 'lfplug_nowhere' (No module named "
        "'lfplug_nowhere'); is its folder on PYTHONPATH?\n"
    )
    assert os.environ["LOOKFEEL_PLUGINS"] == f"{good},lfplug_nowhere"
    assert good in backbone_names()  # the variable's own module came first


def test_a_file_given_to_the_plugin_option_names_the_module_to_give(
    plugin, tmp_path: Path, monkeypatch, capsys
):
    """QA: ``lookfeel --plugin plug/my_ext.py`` blamed LOOKFEEL_PLUGINS, which the user never
    set."""
    args = ["--plugin", "plug/my_ext.py", "data", "info", str(tmp_path)]
    assert main(args) == 1
    assert capsys.readouterr().err == (
        "lookfeel: --plugin: 'plug/my_ext.py' is a file, not a module name: put its folder on "
        "PYTHONPATH and name the module (PYTHONPATH=plug lookfeel --plugin my_ext)\n"
    )
    assert os.environ["LOOKFEEL_PLUGINS"] == ""  # nothing added for the workers


def _install(folder: Path, package: str, entry_points: str) -> None:
    """Make ``folder`` (on sys.path) hold an installed package's metadata declaring
    ``entry_points`` (the lines of its ``[lookfeel.plugins]`` group), as pip would write it
    from ``[project.entry-points."lookfeel.plugins"]`` in its pyproject.toml."""
    info = folder / f"{package.replace('-', '_')}-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {package}\nVersion: 1.0\n", encoding="utf-8"
    )
    (info / "entry_points.txt").write_text(
        f"[lookfeel.plugins]\n{entry_points}\n", encoding="utf-8"
    )


def test_entry_points_are_loaded_once_modules_imported_functions_called(
    plugin, tmp_path: Path, monkeypatch
):
    mod_name, fn_name = plugin("lfplug_ep_module"), plugin("lfplug_ep_function")
    _install(tmp_path / "plugins", "lab-ext", f"mine = {mod_name}\nsetup = {fn_name}:setup")
    asked: list[str] = []

    def entry_points(*, group: str) -> object:
        asked.append(group)
        return _ENTRY_POINTS(group=group)

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    load_plugins()
    load_plugins()
    assert asked == ["lookfeel.plugins"]
    assert mod_name in backbone_names() and fn_name in backbone_names()
    assert sys.modules[fn_name].CALLS == [1]  # called once


def test_an_entry_point_that_fails_names_its_package(plugin, tmp_path: Path, monkeypatch):
    _install(tmp_path / "plugins", "lab-ext", "gone = lfplug_gone:setup")
    monkeypatch.setattr(importlib.metadata, "entry_points", _ENTRY_POINTS)
    with pytest.warns(PluginWarning) as caught:
        load_plugins()
    assert [str(w.message) for w in caught] == [
        "entry point 'gone' (lookfeel.plugins) of package lab-ext: cannot load "
        "'lfplug_gone:setup' (ModuleNotFoundError: No module named 'lfplug_gone'); lookfeel "
        "goes on without it"
    ]


def _entry_point(name: str, value: str) -> importlib.metadata.EntryPoint:
    return importlib.metadata.EntryPoint(name=name, value=value, group=plugins.ENTRY_POINT_GROUP)


def test_a_broken_entry_point_is_one_warning_and_every_command_goes_on(
    plugin, tiny_dataset: Path, tmp_path: Path, monkeypatch, capsys
):
    """QA: one installed package whose entry point failed to import stopped every command,
    even ``lookfeel data info``. It is one warning line naming it; the other entry points load;
    a module named with --plugin that fails is still an error."""
    good = plugin("lfplug_ep_good")
    broken = tmp_path / "plugins" / "lfplug_ep_broken.py"
    broken.write_text("import lfplug_missing_dependency\n", encoding="utf-8")
    eps = [
        _entry_point("broken", "lfplug_ep_broken"),
        _entry_point("calls", f"{good}:nowhere"),
        _entry_point("good", good),
    ]
    monkeypatch.setattr(plugins, "_entry_points", lambda: eps)
    from lookfeel.cli import run

    assert run(["data", "info", str(tiny_dataset)]) == 0
    out = capsys.readouterr()
    assert "fabrics" in out.out
    assert out.err.splitlines() == [
        "lookfeel: warning: entry point 'broken' (lookfeel.plugins): cannot load "
        "'lfplug_ep_broken' (ModuleNotFoundError: No module named 'lfplug_missing_dependency', "
        f"at {broken}:1); lookfeel goes on without it",
        "lookfeel: warning: entry point 'calls' (lookfeel.plugins): cannot load "
        f"'{good}:nowhere' (AttributeError: module '{good}' has no attribute 'nowhere'); "
        "lookfeel goes on without it",
    ]
    assert good in backbone_names()  # the entry point after the broken ones loaded
    # A name no loaded plugin registers names the entry points that did not load.
    with pytest.raises(ConfigError) as e:
        ModelConfig(backbone="lfplug_ep_broken")
    assert str(e.value).endswith(
        "the plugins loaded (entry point good) register no such name; entry point 'broken' = "
        "'lfplug_ep_broken' did not load (ModuleNotFoundError: No module named "
        "'lfplug_missing_dependency'); entry point 'calls' = 'lfplug_ep_good:nowhere' did not "
        "load (AttributeError: module 'lfplug_ep_good' has no attribute 'nowhere'))"
    )
    # Named with --plugin, a module that fails is an error in one line, as before.
    plugins._reset()
    assert run(["--plugin", "lfplug_ep_broken", "data", "info", str(tiny_dataset)]) == 1
    assert capsys.readouterr().err == (
        "lookfeel: --plugin: cannot import 'lfplug_ep_broken' (ModuleNotFoundError: No module "
        f"named 'lfplug_missing_dependency', at {broken}:1)\n"
    )


def test_a_spawned_reproduce_worker_loads_the_plugins(plugin, monkeypatch):
    """`lookfeel reproduce --workers N` trains in spawned processes, which run none of the
    parent's imports: its worker's start-up loads LOOKFEEL_PLUGINS (inherited) itself."""
    from lookfeel.reproduce.run import _start_worker

    name = plugin("lfplug_spawned")
    monkeypatch.setenv("LOOKFEEL_PLUGINS", name)
    with ProcessPoolExecutor(
        1, mp_context=get_context("spawn"), initializer=_start_worker, initargs=(os.getpid(), 1)
    ) as pool:
        assert name in pool.submit(backbone_names).result(timeout=120)
    assert name not in backbone_names()  # the worker's own doing, not this process's


_OVERRIDE = """\
from torch import nn

from lookfeel.models import Backbone, register_backbone


class Residual(Backbone):
    freeze_points = {"none": 0}

    def _build(self, freeze, dropout, width):
        conv = nn.Conv2d(self.stem_channels, 8, 3, 2, 1)
        self.conv = nn.Sequential(conv, nn.AdaptiveAvgPool2d(1))
        self._set_stages([self.conv, nn.Flatten(1)], "none", embed_dim=8)

    def forward(self, x):
        return self.head(self.trunk(x)) + 1


register_backbone("lfplug_residual", Residual)
"""

_CLASH = """\
from lookfeel.models import register_backbone
from lookfeel.models.compact import CompactCNN


class Mine(CompactCNN):
    pass


register_backbone("compact", Mine)
"""


_BAD_NAME = """\
from lookfeel.models import register_backbone
from lookfeel.models.compact import CompactCNN


@register_backbone("My Net!")
class Mine(CompactCNN):
    pass
"""

_BAD_FREEZE_POINT = """\
from lookfeel.models import register_backbone
from lookfeel.models.compact import CompactCNN


class Mine(CompactCNN):
    freeze_points = {"none": 0, "all": -1}


register_backbone("lfplug_negative", Mine)
"""


@pytest.mark.parametrize(
    ("source", "message"),
    [
        (
            _BAD_NAME,
            "PluginError: backbone name 'My Net!' cannot be written as model.backbone in a "
            "config: use only letters, digits, _, - and ., beginning with a letter (e.g. "
            "my_net), at {path}:5",
        ),
        (
            _BAD_FREEZE_POINT,
            "BackboneError: backbone 'lfplug_negative': Mine.freeze_points['all'] is -1; a "
            "freeze point's value is the number of stages in the trunk, an int >= 0, at "
            "{path}:9",
        ),
        (
            _OVERRIDE,
            "TypeError: backbone 'lfplug_residual': Residual defines forward(), which lookfeel "
            "never calls (it runs the stages given to _set_stages): make it a stage, at {path}:18",
        ),
        (
            _CLASH,
            "ValueError: backbone 'compact' is already registered "
            "(lookfeel.models.compact.CompactCNN), at {path}:9",
        ),
    ],
    ids=["bad-name", "negative-freeze-point", "forward-defined", "name-clash"],
)
def test_a_backbone_lookfeel_cannot_run_as_written_is_refused_at_the_plugins_line(
    plugin, tmp_path: Path, monkeypatch, source: str, message: str
):
    """QA: a plugin backbone's own forward() (a residual connection) was never called and
    nothing said so; a refused name was located in lookfeel's registry, not the plugin."""
    name = plugin("lfplug_contract")
    path = tmp_path / "plugins" / f"{name}.py"
    path.write_text(source, encoding="utf-8")
    monkeypatch.setenv("LOOKFEEL_PLUGINS", name)
    with pytest.raises(PluginError) as e:
        load_plugins()
    assert str(e.value) == (
        f"LOOKFEEL_PLUGINS: cannot import 'lfplug_contract' ({message.format(path=path)})"
    )


def test_an_error_s_first_sentence_keeps_its_example() -> None:
    """QA: ``error_line`` cut "... stages in the trunk, e.g. {"none": 0}" at "e.g"."""
    from lookfeel.errors import error_line

    e = TypeError('point -> stages, e.g. {"none": 0}, i.e. a dict. More follows. And more')
    assert error_line(e) == 'TypeError: point -> stages, e.g. {"none": 0}, i.e. a dict'


def test_a_name_a_config_cannot_give_is_refused_when_registered() -> None:
    """QA: ``register_backbone("My Net!")`` was accepted, though no config can select it
    (``--set model.backbone=My Net!``); so was such a loss name. A plain name registers and is
    given through --set as written; every built-in name is one."""
    from lookfeel.config.loss import loss_kinds
    from lookfeel.losses import register_loss
    from lookfeel.models import register_backbone
    from lookfeel.plugins import check_registry_name

    from ._registry import MeanTripletLoss, TinyViT

    rule = "only letters, digits, _, - and ., beginning with a letter (e.g. my_net)"
    with restored_registries():
        for register, what, key in (
            (register_backbone, "backbone", "model.backbone"),
            (register_loss, "loss", "loss.kind"),
        ):
            for name in ("My Net!", "2net", "", None):
                with pytest.raises(PluginError) as e:
                    register(name)  # type: ignore[call-overload]
                assert str(e.value) == (
                    f"{what} name {name!r} cannot be written as {key} in a config: use {rule}"
                )
            with pytest.raises(PluginError) as e:
                register("yes")  # type: ignore[call-overload]
            assert str(e.value) == (
                f"{what} name 'yes' cannot be written as {key} in a config, which reads it as "
                f"True: choose another name of {rule}"
            )
        for name in backbone_names():
            check_registry_name(name, "backbone", "model.backbone")
        for name in loss_kinds():
            check_registry_name(name, "loss", "loss.kind")

        class Dotted(TinyViT):
            name = "my-net.v2"

        register_backbone("my-net.v2", Dotted)
        register_loss("my-loss.v2", lambda c: MeanTripletLoss(c.triplet_margin))
        config = load_config(
            RunConfig, overrides=["model.backbone=my-net.v2", "loss.kind=my-loss.v2"]
        )
        assert (config.model.backbone, config.loss.kind) == ("my-net.v2", "my-loss.v2")


def test_the_config_registries_refuse_a_name_a_config_cannot_give_as_plugins_do() -> None:
    """QA: ``register_loss_kind("My Net!")`` and ``register_backbone_spec`` of such a name,
    called directly, were accepted (``""`` and ``None`` refused with another message), so a
    config could not select what they registered. Now they refuse it with the one-line
    `PluginError` that `register_loss` and `register_backbone` give, and register nothing."""
    from lookfeel.config.loss import loss_kinds, register_loss_kind
    from lookfeel.config.model import BackboneSpec, register_backbone_spec

    rule = "only letters, digits, _, - and ., beginning with a letter (e.g. my_net)"
    with restored_registries():
        before = (loss_kinds(), backbone_names())
        for name in ("My Net!", "2net", "", None):
            with pytest.raises(PluginError) as e:
                register_loss_kind(name)  # type: ignore[arg-type]
            assert str(e.value) == (
                f"loss name {name!r} cannot be written as loss.kind in a config: use {rule}"
            )
            with pytest.raises(PluginError) as e:
                register_backbone_spec(BackboneSpec(name, ("none",)))  # type: ignore[arg-type]
            assert str(e.value) == (
                f"backbone name {name!r} cannot be written as model.backbone in a config: use "
                f"{rule}"
            )
        with pytest.raises(PluginError, match=r"reads it as None: choose another name of only"):
            register_loss_kind("null")
        with pytest.raises(PluginError, match=r"reads it as False: choose another name of only"):
            register_backbone_spec(BackboneSpec("off", ("none",)))
        assert (loss_kinds(), backbone_names()) == before
        register_loss_kind("my-loss.v2")
        register_backbone_spec(BackboneSpec("my-net.v2", ("none",)))
        config = load_config(
            RunConfig, overrides=["model.backbone=my-net.v2", "loss.kind=my-loss.v2"]
        )
        assert (config.model.backbone, config.loss.kind) == ("my-net.v2", "my-loss.v2")


def test_a_freeze_point_beyond_the_backbone_s_stages_is_refused_when_built() -> None:
    """QA: a ``freeze_points`` value above the stages a backbone builds was accepted (it froze
    every stage, whatever the point's name said). The stages exist only once it is built:
    refused then, naming the backbone, the point and the count."""
    from lookfeel.models import BackboneError, create_backbone, register_backbone

    from ._registry import TinyViT  # three stages

    class Short(TinyViT):
        name = "lfplug_short"
        freeze_points: ClassVar[dict[str, int]] = {"none": 0, "to_patches": 1, "all": 4}

    with restored_registries():
        register_backbone("lfplug_short", Short)
        with pytest.raises(BackboneError) as e:
            create_backbone("lfplug_short", freeze="none", width=8)
        assert str(e.value) == (
            f"lfplug_short ({Short.__module__}.{Short.__qualname__}): freeze point 'all' puts 4 "
            "stages in the trunk, but the backbone has 3 (the stages given to _set_stages); a "
            "freeze point's value is at most 3"
        )


_UNPOOLED = """\
from torch import nn

from lookfeel.models import Backbone, register_backbone


@register_backbone("lfplug_unpooled")
class Unpooled(Backbone):
    freeze_points = {"none": 0}
    min_size = 8

    def _build(self, freeze, dropout, width):
        self.conv = nn.Conv2d(self.stem_channels, 8, 3, 2, 1)
        self._set_stages([self.conv], "none", embed_dim=8)  # (N, 8, H, W): never pooled
"""


def test_a_run_whose_plugin_fails_before_its_first_checkpoint_leaves_out_as_found(
    plugin, tiny_dataset: Path, tmp_path: Path, capsys
):
    """QA: a run whose plugin backbone failed at its first batch left config.yaml and
    split.json in --out, which then looked like a run (``--resume`` read that config.yaml,
    and said there was nothing to resume). The folder is left as the run found it: one it
    made is gone, an empty one it was given stays empty."""
    name = plugin("lfplug_unpooled")
    (tmp_path / "plugins" / f"{name}.py").write_text(_UNPOOLED, encoding="utf-8")
    given = tmp_path / "given"
    given.mkdir()
    for out in (tmp_path / "runs" / "first", given):
        args = ["--plugin", name, "train", "--config", str(TINY_CONFIG), "--data"]
        args += [str(tiny_dataset), "--out", str(out), "--set", f"model.backbone={name}"]
        assert main(args) == 1
        err = capsys.readouterr().err
        assert err.startswith(
            "lookfeel: lfplug_unpooled (lfplug_unpooled.Unpooled): returned embeddings of shape "
        )
        assert err.count("\n") == 1
    assert not (tmp_path / "runs").exists()
    assert list(given.iterdir()) == []
