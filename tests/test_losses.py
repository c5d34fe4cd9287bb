"""Losses: parity with naive loop oracles, analytic values, symmetry, gradients, the loss dict."""

from __future__ import annotations

import math
import warnings
from typing import get_args

import pytest
import torch

from lookfeel.config import ConfigError, LossConfig, from_dict, load_config
from lookfeel.config.loss import Distance, loss_kinds, unregistered_loss_kinds_allowed
from lookfeel.losses import (
    BatchHardTripletLoss,
    CombinedLoss,
    ContrastiveD3Loss,
    LossError,
    MultiPositiveInfoNCE,
    batch_hard_triplet,
    contrastive_d3,
    create_loss,
    euclidean_distance,
    list_losses,
    masked_cross_entropy,
    masked_mse,
    mean_squared_distance,
    multi_positive_info_nce,
    pairwise_euclidean,
    pairwise_mean_squared,
    register_loss,
    tuple_label,
)
from lookfeel.losses.combined import _DISTANCES, HEAD_TERMS, PAIR_LOSSES, TARGETS
from lookfeel.models import head_key

from ._registry import MeanTripletLoss, restored_registries

torch.set_num_threads(2)

# Hand-placed embeddings: 4 tuples of (depth, colour, touch) in 3-d.
DEPTH = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.3, 0.3, 0.3]]
COLOR = [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.3, -0.3, 0.3]]
TOUCH = [[0.0, 0.0, 0.0], [0.0, 1.0, 1.0], [3.0, 0.0, 0.0], [-0.3, 0.3, 0.2]]
Y = [0.0, 1.0, 1.0, 0.0]


def _t(rows: list[list[float]], dtype: torch.dtype = torch.float64) -> torch.Tensor:
    return torch.tensor(rows, dtype=dtype)


def _dist(a: list[float], b: list[float]) -> float:
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b, strict=True)))


def _msd(a: list[float], b: list[float]) -> float:
    return sum((x - y) ** 2 for x, y in zip(a, b, strict=True)) / len(a)


def _oracle_d3(slots: list[list[list[float]]], y: list[float], margin: float, dist) -> float:
    total = 0.0
    for b in range(len(y)):
        d3 = 0.0
        for i in range(len(slots)):
            for j in range(i + 1, len(slots)):
                d3 += dist(slots[i][b], slots[j][b])
        total += 0.5 * (1 - y[b]) * d3**2 + 0.5 * y[b] * max(0.0, margin - d3) ** 2
    return total / len(y)


# ------------------------------------------------------------------------------------------
# Distances


def test_euclidean_distance_has_finite_zero_gradient_at_identical_embeddings() -> None:
    a = torch.tensor([[0.5, -1.0, 2.0]], requires_grad=True)
    b = a.detach().clone().requires_grad_(True)
    d = euclidean_distance(a, b)
    d.sum().backward()
    assert d.item() == 0.0
    assert a.grad is not None and b.grad is not None
    assert torch.equal(a.grad, torch.zeros_like(a)) and torch.equal(b.grad, torch.zeros_like(b))
    # The naive norm gives NaN there: the test above guards a real failure.
    a2 = a.detach().clone().requires_grad_(True)
    (a2 - a.detach()).pow(2).sum().sqrt().backward()
    assert a2.grad is not None and torch.isnan(a2.grad).all()


def test_pairwise_distances_match_rowwise_and_are_safe_on_duplicates() -> None:
    a = _t(DEPTH).requires_grad_(True)
    b = _t(COLOR)
    d = pairwise_euclidean(a, torch.cat([b, a.detach()]))  # (4, 8); a's own rows included
    for i in range(4):
        for j in range(4):
            assert d[i, j].item() == pytest.approx(_dist(DEPTH[i], COLOR[j]), abs=1e-9)
        assert d[i, 4 + i].item() == pytest.approx(0.0, abs=1e-7)
    d.sum().backward()
    assert a.grad is not None and torch.isfinite(a.grad).all()
    msd = pairwise_mean_squared(_t(DEPTH), _t(COLOR))
    assert msd[1, 2].item() == pytest.approx(_msd(DEPTH[1], COLOR[2]))


# ------------------------------------------------------------------------------------------
# Contrastive loss on D3 (paper equation 2)


@pytest.mark.parametrize("margin", [1.0, 2.0])
def test_contrastive_d3_matches_loop_oracle(margin: float) -> None:
    e = [_t(DEPTH), _t(COLOR), _t(TOUCH)]
    got = contrastive_d3(e, _t([Y])[0], margin=margin)
    want = _oracle_d3([DEPTH, COLOR, TOUCH], Y, margin, _dist)
    assert got.item() == pytest.approx(want, rel=1e-12)
    got_ms = contrastive_d3(e, _t([Y])[0], margin=margin, distance=mean_squared_distance)
    want_ms = _oracle_d3([DEPTH, COLOR, TOUCH], Y, margin, _msd)
    assert got_ms.item() == pytest.approx(want_ms, rel=1e-12)
    assert got.item() != pytest.approx(got_ms.item())  # the flag changes the distance


def test_contrastive_d3_analytic_values() -> None:
    e = torch.tensor([[0.2, -0.4, 1.0]]).repeat(2, 1)  # two tuples, all slots identical
    same = contrastive_d3([e, e.clone(), e.clone()], torch.tensor([0.0, 0.0]))
    assert same.item() == 0.0
    # Identical embeddings labelled different: D3 = 0, so L = m^2 / 2.
    diff = contrastive_d3([e, e.clone()], torch.tensor([1, 1]), margin=2.0)
    assert diff.item() == pytest.approx(2.0)
    # Different fabrics beyond the margin contribute nothing; D3 = 3 * 1 here.
    far = [torch.tensor([[0.0]]), torch.tensor([[1.0]]), torch.tensor([[0.0]])]
    d3 = 1.0 + 1.0 + 0.0
    assert contrastive_d3(far, torch.tensor([1.0]), margin=2.0).item() == 0.0
    assert contrastive_d3(far, torch.tensor([0.0])).item() == pytest.approx(0.5 * d3**2)


def test_contrastive_d3_is_symmetric_under_slot_order() -> None:
    y = _t([Y])[0]
    a = contrastive_d3([_t(DEPTH), _t(COLOR), _t(TOUCH)], y)
    b = contrastive_d3([_t(TOUCH), _t(DEPTH), _t(COLOR)], y)
    assert a.item() == pytest.approx(b.item(), rel=1e-12)


def test_contrastive_d3_gradcheck_and_gradient_at_zero() -> None:
    g = torch.Generator().manual_seed(0)
    e = [torch.randn(3, 4, generator=g, dtype=torch.float64, requires_grad=True) for _ in range(3)]
    y = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    # margin 20 keeps the Y = 1 tuple inside the margin, away from the hinge's kink.
    assert torch.autograd.gradcheck(lambda *x: contrastive_d3(list(x), y, margin=20.0), e)
    assert torch.autograd.gradcheck(
        lambda *x: contrastive_d3(list(x), y, 20.0, mean_squared_distance), e
    )
    same = torch.ones(2, 4, requires_grad=True)
    loss = contrastive_d3([same, same, same], torch.tensor([0.0, 1.0]))
    loss.backward()
    assert same.grad is not None and torch.isfinite(same.grad).all()


def test_contrastive_module_names_terms_and_derives_y_from_fabric() -> None:
    emb = {"depth": _t(DEPTH), "color": _t(COLOR), "touch": _t(TOUCH)}
    fabric = {
        "depth": torch.tensor([1, 2, 3, 4]),
        "color": torch.tensor([1, 5, 3, 4]),
        "touch": torch.tensor([1, 2, 6, 4]),
    }
    assert tuple_label(fabric, ["depth", "color", "touch"]).tolist() == Y
    by_y = ContrastiveD3Loss()(emb, y=_t([Y])[0])
    by_fabric = ContrastiveD3Loss()(emb, fabric=fabric)
    assert list(by_y) == ["depth_color_touch_loss"]
    assert by_y["depth_color_touch_loss"].item() == pytest.approx(
        by_fabric["depth_color_touch_loss"].item()
    )
    pairs = ContrastiveD3Loss(per_pair=True)(emb, fabric=fabric)
    assert list(pairs) == ["depth_color_loss", "depth_touch_loss", "color_touch_loss"]
    # depth and touch agree on tuple 1 (fabric 2): that pair's own label is 0 there.
    want = _oracle_d3([DEPTH, TOUCH], [0.0, 0.0, 1.0, 0.0], 2.0, _dist)
    assert pairs["depth_touch_loss"].item() == pytest.approx(want)
    with pytest.raises(ValueError, match="needs y"):
        ContrastiveD3Loss()(emb)
    with pytest.raises(ValueError, match="at least 2 slots"):
        ContrastiveD3Loss()({"depth": _t(DEPTH)}, y=_t([Y])[0])


# ------------------------------------------------------------------------------------------
# Multi-positive InfoNCE


def _oracle_infonce(a, b, fa, fb, scale: float) -> float:
    def unit(v):
        n = math.sqrt(sum(x * x for x in v))
        return [x / n for x in v]

    a = [unit(v) for v in a]
    b = [unit(v) for v in b]

    def direction(q, g, fq, fg) -> float:
        losses = []
        for i in range(len(q)):
            logits = [
                scale * sum(x * y for x, y in zip(q[i], g[j], strict=True)) for j in range(len(g))
            ]
            lse = math.log(sum(math.exp(z) for z in logits))
            pos = [j for j in range(len(g)) if fg[j] == fq[i]]
            if not pos:
                continue
            ce = -sum(logits[j] - lse for j in pos) / len(pos)
            losses.append(ce - math.log(len(pos)))
        return sum(losses) / len(losses)

    return 0.5 * (direction(a, b, fa, fb) + direction(b, a, fb, fa))


def test_infonce_matches_loop_oracle_with_multiple_positives() -> None:
    a = [*DEPTH[1:], [1.0, 1.0, 1.0]]
    b = [*COLOR[1:], [0.5, 0.1, 0.0]]
    fa = [1, 1, 2, 3]  # fabric 1 has two items in a, and two positives in b
    fb = [1, 2, 1, 4]  # fabric 3 has no positive in b; fabric 4 none in a
    got = multi_positive_info_nce(_t(a), _t(b), torch.tensor(fa), torch.tensor(fb), 5.0)
    assert got.item() == pytest.approx(_oracle_infonce(a, b, fa, fb, 5.0), rel=1e-10)


def test_infonce_is_zero_when_same_fabric_items_coincide_and_symmetric() -> None:
    # Items of one fabric share a direction; fabrics are orthogonal; huge scale.
    a = _t([[1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    f = torch.tensor([7, 7, 8, 9])
    assert multi_positive_info_nce(a, a.clone(), f, f, 1e3).item() == pytest.approx(0, abs=1e-9)
    # Single-positive CLIP targets would penalise the false negative (rows 0 and 1).
    g = torch.Generator().manual_seed(1)
    x, y = torch.randn(5, 4, generator=g), torch.randn(5, 4, generator=g)
    fx, fy = torch.tensor([0, 1, 1, 2, 3]), torch.tensor([1, 0, 2, 2, 3])
    ab = multi_positive_info_nce(x, y, fx, fy, 3.0)
    ba = multi_positive_info_nce(y, x, fy, fx, 3.0)
    assert ab.item() == pytest.approx(ba.item(), rel=1e-6)


def test_infonce_gradcheck_and_temperature() -> None:
    g = torch.Generator().manual_seed(2)
    a = torch.randn(4, 3, generator=g, dtype=torch.float64, requires_grad=True)
    b = torch.randn(4, 3, generator=g, dtype=torch.float64, requires_grad=True)
    fa, fb = torch.tensor([0, 0, 1, 2]), torch.tensor([0, 1, 1, 2])
    assert torch.autograd.gradcheck(lambda x, y: multi_positive_info_nce(x, y, fa, fb, 4.0), (a, b))
    learnt = MultiPositiveInfoNCE(temperature=0.5, learn_temperature=True)
    fixed = MultiPositiveInfoNCE(temperature=0.5, learn_temperature=False)
    assert len(list(learnt.parameters())) == 1 and not list(fixed.parameters())
    emb = {"depth": a.float().detach(), "touch": b.float().detach()}
    fab = {"depth": fa, "touch": fb}
    out = learnt(emb, fabric=fab)
    assert list(out) == ["depth_touch_loss"]
    assert out["depth_touch_loss"].item() == pytest.approx(
        fixed(emb, fabric=fab)["depth_touch_loss"].item()
    )
    out["depth_touch_loss"].backward()
    assert learnt.log_logit_scale is not None and learnt.log_logit_scale.grad is not None
    assert learnt.log_logit_scale.grad.item() != 0.0
    clamped = MultiPositiveInfoNCE(temperature=0.001, max_logit_scale=100.0)
    assert float(torch.as_tensor(clamped.logit_scale()).detach()) == pytest.approx(100.0)
    with pytest.raises(ValueError, match="fabric ids"):
        learnt(emb)


# ------------------------------------------------------------------------------------------
# Batch-hard triplet


def _oracle_triplet(a, b, fa, fb, margin: float) -> float:
    losses = []
    for i in range(len(a)):
        pos = [_dist(a[i], b[j]) for j in range(len(b)) if fb[j] == fa[i]]
        neg = [_dist(a[i], b[j]) for j in range(len(b)) if fb[j] != fa[i]]
        if pos and neg:
            losses.append(max(0.0, max(pos) - min(neg) + margin))
    return sum(losses) / len(losses)


def test_triplet_matches_loop_oracle_and_is_symmetric() -> None:
    fa, fb = [1, 1, 2, 3], [1, 2, 2, 1]
    got = batch_hard_triplet(_t(DEPTH), _t(TOUCH), torch.tensor(fa), torch.tensor(fb), 1.5)
    assert got.item() == pytest.approx(_oracle_triplet(DEPTH, TOUCH, fa, fb, 1.5), rel=1e-9)
    loss = BatchHardTripletLoss(margin=1.5)
    f = {"depth": torch.tensor(fa), "touch": torch.tensor(fb)}
    one = loss({"depth": _t(DEPTH), "touch": _t(TOUCH)}, fabric=f)["depth_touch_loss"]
    two = loss({"touch": _t(TOUCH), "depth": _t(DEPTH)}, fabric=f)["touch_depth_loss"]
    want = 0.5 * (
        _oracle_triplet(DEPTH, TOUCH, fa, fb, 1.5) + _oracle_triplet(TOUCH, DEPTH, fb, fa, 1.5)
    )
    assert one.item() == pytest.approx(want, rel=1e-9)
    assert two.item() == pytest.approx(one.item(), rel=1e-12)


def test_triplet_gradcheck_and_no_valid_anchor() -> None:
    g = torch.Generator().manual_seed(3)
    a = torch.randn(4, 3, generator=g, dtype=torch.float64, requires_grad=True)
    b = torch.randn(4, 3, generator=g, dtype=torch.float64, requires_grad=True)
    fa, fb = torch.tensor([0, 0, 1, 1]), torch.tensor([1, 0, 0, 1])
    assert torch.autograd.gradcheck(
        lambda x, y: batch_hard_triplet(x, y, fa, fb, margin=10.0), (a, b)
    )
    assert torch.autograd.gradcheck(
        lambda x, y: batch_hard_triplet(x, y, fa, fb, 10.0, pairwise_mean_squared), (a, b)
    )
    same = torch.zeros(2)
    z = batch_hard_triplet(a[:2], b[:2], same, same)  # no negative anywhere
    z.backward()
    assert z.item() == 0.0 and a.grad is not None and torch.isfinite(a.grad).all()


# ------------------------------------------------------------------------------------------
# Auxiliary terms


def test_masked_cross_entropy_ignores_unknown_clusters() -> None:
    logits = torch.tensor([[2.0, 0.0, -1.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0]], requires_grad=True)
    got = masked_cross_entropy(logits, torch.tensor([0, -1, 2]))
    want = (
        sum(-(logits[i, t] - torch.logsumexp(logits[i], 0)).item() for i, t in [(0, 0), (2, 2)]) / 2
    )
    assert got.item() == pytest.approx(want)
    none = masked_cross_entropy(logits, torch.tensor([-1, -1, -1]))
    none.backward()
    assert none.item() == 0.0 and logits.grad is not None and (logits.grad == 0).all()


def test_masked_mse_ignores_nan_targets() -> None:
    pred = torch.tensor([[1.0, 2.0], [3.0, 4.0]], requires_grad=True)
    target = torch.tensor([[0.0, float("nan")], [float("nan"), 1.0]])
    got = masked_mse(pred, target)
    assert got.item() == pytest.approx((1.0**2 + 3.0**2) / 2)
    got.backward()
    assert pred.grad is not None
    assert torch.equal(pred.grad, torch.tensor([[1.0, 0.0], [0.0, 3.0]]))
    pred.grad = None
    empty = masked_mse(pred, torch.full((2, 2), float("nan")))
    empty.backward()
    assert empty.item() == 0.0 and pred.grad is not None and (pred.grad == 0).all()


# ------------------------------------------------------------------------------------------
# The combined loss and its config


def _outputs() -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(4)
    out = {s: torch.randn(4, 5, generator=g, requires_grad=True) for s in ("depth", "touch")}
    for s in ("depth", "touch"):
        out[head_key(s, "cluster")] = torch.randn(4, 8, generator=g, requires_grad=True)
        out[head_key(s, "property")] = torch.randn(4, 2, generator=g, requires_grad=True)
    return out


@pytest.mark.parametrize("kind", ["contrastive", "infonce", "triplet"])
def test_create_loss_returns_named_terms_and_their_sum(kind: str) -> None:
    loss_fn = create_loss(LossConfig(kind=kind, cluster_weight=0.5, property_weight=2.0))
    out = _outputs()
    fabric = {"depth": torch.tensor([0, 1, 2, 0]), "touch": torch.tensor([0, 1, 3, 0])}
    cluster = {"depth": torch.tensor([1, 2, -1, 1]), "touch": torch.tensor([1, 2, 3, 1])}
    nan = float("nan")
    props = {s: torch.tensor([[0.0, 1.0], [nan, 2.0], [1.0, nan], [0.0, 1.0]]) for s in fabric}
    terms = loss_fn(out, fabric=fabric, cluster=cluster, properties=props)
    assert list(terms) == ["depth_touch_loss", "cluster_loss", "property_loss", "loss"]
    assert all(v.dim() == 0 and torch.isfinite(v) for v in terms.values())
    ce = sum(masked_cross_entropy(out[head_key(s, "cluster")], cluster[s]).item() for s in cluster)
    mse = sum(masked_mse(out[head_key(s, "property")], props[s]).item() for s in props)
    assert terms["cluster_loss"].item() == pytest.approx(0.5 * ce)
    assert terms["property_loss"].item() == pytest.approx(2.0 * mse)
    total = terms["depth_touch_loss"] + terms["cluster_loss"] + terms["property_loss"]
    assert terms["loss"].item() == pytest.approx(total.item())
    terms["loss"].backward()
    assert all(v.grad is not None and torch.isfinite(v.grad).all() for v in out.values())


def test_combined_loss_errors_and_weights() -> None:
    out = {"depth": torch.randn(2, 3), "touch": torch.randn(2, 3)}
    loss_fn = create_loss(LossConfig())
    with pytest.raises(ValueError, match="'depth/cluster'"):
        loss_fn(out, y=torch.zeros(2), cluster={"depth": torch.zeros(2, dtype=torch.long)})
    only_pair = loss_fn(out, y=torch.zeros(2))
    assert list(only_pair) == ["depth_touch_loss", "loss"]
    silent = CombinedLoss(ContrastiveD3Loss(), pair_weight=0.0)
    with pytest.raises(ValueError, match="no loss term"):
        silent(out, y=torch.zeros(2))
    snn = create_loss(LossConfig())(
        {"depth": out["depth"], "depth.1": out["touch"]}, y=torch.ones(2)
    )
    assert "depth_depth1_loss" in snn


def test_pair_weights_scale_or_leave_out_one_pair_of_slots() -> None:
    g = torch.Generator().manual_seed(7)
    out = {
        s: torch.randn(6, 4, generator=g, requires_grad=True) for s in ("depth", "color", "touch")
    }
    fabric = {s: torch.tensor([0, 1, 2, 0, 1, 2]) for s in out}
    plain = create_loss(LossConfig(kind="infonce", learn_temperature=False))(out, fabric=fabric)
    assert list(plain)[:3] == ["depth_color_loss", "depth_touch_loss", "color_touch_loss"]
    cfg = load_config(
        LossConfig,
        overrides=[
            "kind=infonce",
            "learn_temperature=false",
            "pair_weights={touch_color: 0, depth_touch: 0.5}",
        ],
    )
    terms = create_loss(cfg)(out, fabric=fabric)
    assert "color_touch_loss" not in terms  # either order names the pair
    assert terms["depth_touch_loss"].item() == pytest.approx(0.5 * plain["depth_touch_loss"].item())
    assert terms["depth_color_loss"].item() == pytest.approx(plain["depth_color_loss"].item())
    assert terms["loss"].item() == pytest.approx(
        plain["depth_color_loss"].item() + 0.5 * plain["depth_touch_loss"].item()
    )
    terms["loss"].backward()  # the colour-touch term sends nothing back: touch learns from depth
    g_touch = out["touch"].grad
    assert g_touch is not None and torch.isfinite(g_touch).all() and g_touch.abs().sum() > 0
    # A pair the run does not train is ignored; leaving out every pair it trains is refused.
    depth_color = {"depth": out["depth"], "color": out["color"]}
    two = create_loss(cfg)(depth_color, fabric=fabric)
    assert two["loss"].item() == pytest.approx(plain["depth_color_loss"].item())
    only = load_config(LossConfig, overrides=["kind=infonce", "pair_weights={color_depth: 0}"])
    with pytest.raises(ConfigError, match=r"leaves out every pair this run trains \(depth_color\)"):
        create_loss(only)(depth_color, fabric=fabric)
    for bad in ("colortouch", "color_wind", "color_touch_depth"):
        with pytest.raises(ConfigError, match=f"loss.pair_weights.{bad}: name a pair"):
            load_config(LossConfig, overrides=[f"pair_weights={{{bad}: 1}}"])
    with pytest.raises(ConfigError, match=r"loss.pair_weights.color_touch: must be a finite"):
        load_config(LossConfig, overrides=["pair_weights={color_touch: -1}"])


def test_create_loss_refuses_an_unknown_kind_or_distance() -> None:
    # A LossConfig checks its Literal choices, so force a bad one past that check: create_loss
    # must say so rather than fall through to some objective.
    for field, bad, allowed in [
        ("kind", "arcface", "contrastive, infonce, triplet"),
        ("distance", "cosine", "euclidean, mean_squared"),
    ]:
        cfg = LossConfig()
        object.__setattr__(cfg, field, bad)
        with pytest.raises(ValueError, match=f"loss.{field}: '{bad}' is not one of {allowed}"):
            create_loss(cfg)
    assert set(loss_kinds()) == set(PAIR_LOSSES) and set(get_args(Distance)) == set(_DISTANCES)


def test_a_loss_registered_from_ones_own_module_is_one_the_config_takes() -> None:
    """QA: ``loss.kind`` was checked against a Literal while the losses lived in a private
    dict, so a loss of one's own needed both patched. One call now registers both."""
    with pytest.raises(ConfigError, match="loss.kind: 'meantriplet' is not one of contrastive"):
        LossConfig(kind="meantriplet")
    with restored_registries():

        @register_loss("meantriplet")
        def build(config: LossConfig) -> MeanTripletLoss:
            return MeanTripletLoss(config.triplet_margin)

        register_loss("meantriplet", build)  # a module imported twice: nothing changes
        assert loss_kinds() == ("contrastive", "infonce", "meantriplet", "triplet")
        cfg = load_config(LossConfig, overrides=["kind=meantriplet", "triplet_margin=0.5"])
        loss_fn = create_loss(cfg)
        assert isinstance(loss_fn.pair_loss, MeanTripletLoss) and loss_fn.pair_loss.margin == 0.5
        fabric = {"depth": torch.tensor([0, 1, 2, 0]), "touch": torch.tensor([0, 1, 3, 0])}
        terms = loss_fn(_outputs(), fabric=fabric)
        assert list(terms) == ["depth_touch_loss", "loss"] and terms["loss"].dim() == 0
        with pytest.raises(ConfigError, match="'arcface' is not one of contrastive, infonce, m"):
            LossConfig(kind="arcface")
        with pytest.raises(ValueError, match="'triplet' is already registered .*_triplet"):
            register_loss("triplet", build)
    assert "meantriplet" not in loss_kinds() and "meantriplet" not in PAIR_LOSSES
    # A trained run's record may name a loss this process lacks: read as such, it loads with a
    # warning (the loss plays no part in embedding); building the loss still refuses it.
    warns = pytest.warns(UserWarning, match="loss.kind: 'meantriplet' is not registered in this")
    with warns, unregistered_loss_kinds_allowed():
        record = LossConfig(kind="meantriplet")
    with pytest.raises(ValueError, match="loss.kind: 'meantriplet' is not one of contrastive"):
        create_loss(record)


class _PerRow(torch.nn.Module):
    """A loss of one's own that forgets to reduce its term: (B,) instead of a scalar."""

    def forward(self, embeddings, y=None, fabric=None):
        a, b = embeddings.values()
        return {"depth_touch_loss": (a - b).pow(2).sum(-1)}


def test_a_loss_term_that_is_not_a_scalar_is_refused_naming_it() -> None:
    """QA: a (B,) term crashed at .backward() with torch's "grad can be implicitly created
    only for scalar outputs", naming neither the loss nor the term."""
    out = {k: v for k, v in _outputs().items() if "/" not in k}
    with pytest.raises(
        LossError,
        match=r"^the loss _PerRow: term 'depth_touch_loss' has shape "
        r"\(4,\); every term must be a scalar \(a 0-dim tensor\)",
    ):
        CombinedLoss(_PerRow())(out)


def test_loss_config_validates_with_key_names() -> None:
    assert LossConfig().margin == 2.0 and LossConfig().kind == "contrastive"
    cfg = load_config(LossConfig, overrides=["kind=triplet", "distance=mean_squared"])
    assert isinstance(create_loss(cfg).pair_loss, BatchHardTripletLoss)
    assert isinstance(create_loss(LossConfig(kind="infonce")).pair_loss, MultiPositiveInfoNCE)
    for bad, key in [
        ({"kind": "arcface"}, "loss.kind"),
        ({"distance": "cosine"}, "loss.distance"),
        ({"margin": 0}, "loss.margin"),
        ({"temperature": -1}, "loss.temperature"),
        ({"temperature": 0.001}, "loss.temperature"),
        ({"cluster_weight": -1}, "loss.cluster_weight"),
        ({"margn": 1}, "margn"),
    ]:
        with pytest.raises(ConfigError, match=key):
            from_dict(LossConfig, bad)


class _Detached(torch.nn.Module):
    """A loss of one's own whose term is cut from the embeddings (``.item()`` back to a tensor)."""

    def forward(self, embeddings, y=None, fabric=None):
        a, b = embeddings.values()
        return {"depth_touch_loss": torch.tensor((a - b).pow(2).mean().item())}


def test_a_loss_that_gives_nothing_to_train_with_is_one_line_naming_it() -> None:
    """QA: a build function returning None failed at the first step with "'NoneType' object
    is not callable", and a detached term at backward with "element 0 of tensors does not
    require grad": neither named the loss."""
    with restored_registries():
        register_loss("lfnone", lambda config: None)
        with pytest.raises(
            LossError,
            match=r"^loss 'lfnone': its build function tests\.test_losses\..*<lambda> returned "
            r"NoneType, not a torch\.nn\.Module",
        ):
            create_loss(LossConfig(kind="lfnone"))
    out = {k: v.requires_grad_() for k, v in _outputs().items() if "/" not in k}
    with pytest.raises(
        LossError,
        match=r"^the loss _Detached: term 'depth_touch_loss' does not depend on the embeddings",
    ):
        CombinedLoss(_Detached())(out)
    with torch.no_grad():  # scoring: nothing to train, nothing refused
        assert CombinedLoss(_Detached())(out)["loss"].dim() == 0


# ------------------------------------------------------------------------------------------
# A loss of one's own: what it is given, what it may return (session 57's read-through)


def _pair(out: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    return {k: v for k, v in out.items() if "/" not in k}


class _Terms(torch.nn.Module):
    """A loss of one's own returning the terms it was built with: name -> "live" (from the
    embeddings) or "detached" (cut from them)."""

    def __init__(self, terms: dict[str, str]) -> None:
        super().__init__()
        self.terms = terms

    def forward(self, embeddings, y=None, fabric=None):
        a, b = list(embeddings.values())[:2]
        live = (a - b).pow(2).mean()
        return {n: live if how == "live" else live.detach() for n, how in self.terms.items()}


def test_a_term_detached_from_the_embeddings_is_refused_naming_the_kind_and_the_term() -> None:
    """QA (session 57, F3): docs/ARCHITECTURE.md says a term that does not depend on the
    embeddings is refused, but only the total was checked: a detached term beside a live one,
    or a wholly detached pair loss beside a live cluster term, trained on without a word."""
    out = {k: v.requires_grad_() for k, v in _outputs().items()}
    fabric = {"depth": torch.tensor([0, 1, 2, 0]), "touch": torch.tensor([0, 1, 3, 0])}
    cluster = {s: torch.tensor([1, 2, -1, 1]) for s in fabric}
    with restored_registries():
        register_loss(
            "halfdetached", lambda c: _Terms({"live_loss": "live", "dead_loss": "detached"})
        )
        loss_fn = create_loss(LossConfig(kind="halfdetached"))
        with pytest.raises(LossError) as e:
            loss_fn(_pair(out), fabric=fabric)
        assert str(e.value).startswith(
            "the loss 'halfdetached' (_Terms): term 'dead_loss' does not depend on the embeddings"
        )
        assert "\n" not in str(e.value)
        register_loss("alldetached", lambda c: _Terms({"depth_touch_loss": "detached"}))
        with pytest.raises(LossError, match=r"^the loss 'alldetached' \(_Terms\): term 'depth_t"):
            create_loss(LossConfig(kind="alldetached"))(out, fabric=fabric, cluster=cluster)
        with torch.no_grad():  # scoring: nothing to train, nothing refused
            assert set(loss_fn(_pair(out), fabric=fabric)) == {"live_loss", "dead_loss", "loss"}
    # Embeddings that train nothing themselves (a frozen model): nothing to check either.
    frozen = {k: v.detach() for k, v in _pair(out).items()}
    assert CombinedLoss(_Terms({"a_loss": "detached"}))(frozen)["loss"].dim() == 0


@pytest.mark.parametrize("name", ["loss", *HEAD_TERMS])
def test_a_term_named_as_one_of_lookfeel_s_own_is_refused(name: str) -> None:
    """QA (session 57, F4): a term named ``loss`` was merged into the total and vanished from
    the log; one named ``cluster_loss`` was overwritten by the cluster head's term."""
    with restored_registries():
        register_loss("mine", lambda config: _Terms({name: "live"}))
        with pytest.raises(LossError) as e:
            create_loss(LossConfig(kind="mine"))(_pair(_outputs()))
    assert str(e.value).startswith(
        f"the loss 'mine' (_Terms): term {name!r} is named as one of lookfeel's own terms (loss, "
        "cluster_loss, property_loss, class_loss)"
    )


@pytest.mark.parametrize("name", ["mine", "step", "lr", "val/depth_loss", "_loss", "1_loss"])
def test_a_term_not_named_as_a_loss_term_is_refused(name: str) -> None:
    """A term's name goes into each log line beside ``step``, ``lr`` and ``val/...``: it is a
    word ending in ``_loss``, as lookfeel's own terms are."""
    with pytest.raises(LossError, match=rf"^the loss _Terms: term '{name}' is not named as a l"):
        CombinedLoss(_Terms({name: "live"}))(_pair(_outputs()))
    assert "mine_loss" in CombinedLoss(_Terms({"mine_loss": "live"}))(_pair(_outputs()))


def test_a_pair_weight_that_names_no_term_of_the_loss_is_warned_of_once() -> None:
    """QA (session 57, F4): ``loss.pair_weights`` weighs only terms named ``<a>_<b>_loss``; with
    a loss whose terms are named otherwise (or the contrastive loss's one term on D3), a weight
    changed nothing, without a word."""
    out = {s: torch.randn(4, 3, requires_grad=True) for s in ("depth", "color", "touch")}
    fabric = {s: torch.tensor([0, 1, 2, 0]) for s in out}
    with restored_registries():
        register_loss("odd", lambda config: _Terms({"mine_loss": "live"}))
        odd = create_loss(LossConfig(kind="odd", pair_weights={"depth_touch": 0}))
    with pytest.warns(UserWarning) as said:
        first = odd(out, fabric=fabric)
        odd(out, fabric=fabric)  # once
    assert [str(w.message) for w in said] == [
        "loss.pair_weights (depth_touch): the loss 'odd' (_Terms) gives no term named "
        "depth_touch_loss (its terms: mine_loss), so the weight changes nothing; a pair weight "
        "applies to a term named <a>_<b>_loss, as lookfeel.losses.FabricPairLoss names them"
    ]
    assert list(first) == ["mine_loss", "loss"]
    d3 = load_config(LossConfig, overrides=["pair_weights={color_touch: 0}"])
    with pytest.warns(UserWarning, match=r"\(its terms: depth_color_touch_loss\), so the"):
        create_loss(d3)(out, fabric=fabric)
    # Weights that apply, or that name a pair of slots the run does not train: no warning.
    two = {s: out[s] for s in ("depth", "touch")}
    per_pair = load_config(LossConfig, overrides=["kind=infonce", "pair_weights={color_touch: 0}"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        create_loss(per_pair)(out, fabric=fabric)
        create_loss(per_pair)(two, fabric=fabric)
        create_loss(d3)(two, fabric=fabric)


class _Sees(torch.nn.Module):
    """A loss of one's own that takes the cluster and property targets, and an option: it
    keeps what it was given."""

    def __init__(self, alpha: float) -> None:
        super().__init__()
        self.alpha = alpha
        self.given: list[dict[str, object]] = []

    def forward(self, embeddings, y=None, fabric=None, cluster=None, properties=None):
        self.given.append({"fabric": fabric, "cluster": cluster, "properties": properties})
        a, b = embeddings.values()
        return {"depth_touch_loss": self.alpha * (a - b).pow(2).mean()}


class _Everything(torch.nn.Module):
    """A loss of one's own whose ``forward`` takes any keyword."""

    def forward(self, embeddings, **given):
        self.given = given
        a, b = embeddings.values()
        return {"depth_touch_loss": (a - b).pow(2).mean()}


def test_a_loss_of_one_s_own_gets_its_options_and_the_targets_its_forward_names() -> None:
    """QA (session 57, F5): a loss of one's own saw only the embeddings and fabric ids, and
    could have no setting of its own. Its settings are ``loss.options``, and its ``forward``
    is given the batch's cluster, property and class targets that it names; one written as
    before (``embeddings, y, fabric``) works as before."""
    out = _pair(_outputs())
    fabric = {"depth": torch.tensor([0, 1, 2, 0]), "touch": torch.tensor([0, 1, 3, 0])}
    cluster = {s: torch.tensor([1, 2, -1, 1]) for s in fabric}
    props = {s: torch.zeros(4, 2) for s in fabric}
    classes = {s: torch.zeros(4, 0, dtype=torch.long) for s in fabric}
    assert TARGETS == ("cluster", "properties", "classes")
    with restored_registries():
        register_loss("sees", lambda config: _Sees(config.options.get("alpha", 1.0)))
        cfg = load_config(LossConfig, overrides=["kind=sees", "options.alpha=0.25"])
        assert cfg.options == {"alpha": 0.25}
        loss_fn = create_loss(cfg)
        seen = loss_fn.pair_loss
        assert isinstance(seen, _Sees) and seen.alpha == 0.25
        assert loss_fn.pair_targets == ("cluster", "properties")
        # As the trainer calls it for a model without heads: every target in `targets`.
        targets = {"cluster": cluster, "properties": props, "classes": classes}
        terms = loss_fn(out, fabric=fabric, targets=targets)
        assert list(terms) == ["depth_touch_loss", "loss"]  # no head: no head term
        assert seen.given[-1] == {"fabric": fabric, "cluster": cluster, "properties": props}
        # Called as before, it gets the head targets it is given, None for the others.
        loss_fn(out, fabric=fabric)
        assert seen.given[-1] == {"fabric": fabric, "cluster": None, "properties": None}
    everything = CombinedLoss(_Everything())
    everything(out, fabric=fabric, targets=targets)
    assert everything.pair_loss.given == {"y": None, "fabric": fabric, **targets}
    # The built-in objectives and a loss of one's own written as before take none.
    assert create_loss(LossConfig(kind="infonce")).pair_targets == ()
    before = CombinedLoss(MeanTripletLoss(0.2))
    assert before.pair_targets == ()
    assert before(out, fabric=fabric, targets=targets)["loss"].dim() == 0


def test_list_losses_names_the_built_in_and_registered_kinds() -> None:
    """QA (session 57, F10): `list_backbones` had no counterpart for losses."""
    assert list_losses() == ["contrastive", "infonce", "triplet"]
    with restored_registries():
        register_loss("meantriplet", lambda c: MeanTripletLoss(c.triplet_margin))
        assert list_losses() == ["contrastive", "infonce", "meantriplet", "triplet"]
        assert list(loss_kinds()) == list_losses()
