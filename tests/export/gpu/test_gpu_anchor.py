"""``gpu-train --albedo-anchor W``: the albedo held near the frozen warm start's, and nothing else touched by it."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from export.gpu.train import frozen_teacher, step_terms  # noqa: E402
from export.losses import Stage1Loss  # noqa: E402
from export.networks import Stage1Net  # noqa: E402

RES = 64


def _net(seed: int = 0) -> Stage1Net:
    torch.manual_seed(seed)
    net = Stage1Net(width=4, resolution=RES, norm="batch")
    with torch.no_grad():  # norms away from their defaults, as after warm_start.calibrate_norms
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
                m.running_mean.uniform_(-0.1, 0.1)
                m.running_var.uniform_(0.5, 1.5)
    return net


def _batch(n: int = 2, seed: int = 1) -> dict:
    g = torch.Generator().manual_seed(seed)
    mask = torch.zeros(n, 1, RES, RES)
    mask[:, :, 8:56, 16:48] = 1.0  # a person in the middle, background around
    return {"albedo": torch.rand(n, 3, RES, RES, generator=g), "mask": mask,
            "skin": (torch.rand(n, 1, RES, RES, generator=g) > 0.5).float(),
            "transport": torch.randn(n, 9, RES, RES, generator=g) * 0.3, "light": torch.randn(n, 9, 3, generator=g)}


def _nudge(net: Stage1Net, seed: int = 2, scale: float = 0.05) -> None:
    """Move every weight a little: the student after some steps, away from its teacher."""
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in net.parameters():
            p.add_(torch.randn(p.shape, generator=g) * scale * (p.abs().mean() + 1e-3))


def _input(batch: dict) -> torch.Tensor:
    from export.torch_data import render_input

    return (2.0 * render_input(batch) - 1.0) * batch["mask"]


LOSS = Stage1Loss(sf_scale=0.2, band_weight=2.0, direction_weight=5.0)


def test_without_an_anchor_the_terms_are_the_loss_alone():
    """W = 0 is the second lend's objective exactly: no teacher is made, no term is added, the same total."""
    net, batch = _net(), _batch()
    assert frozen_teacher(net, 0.0) is None
    torch.manual_seed(5)  # the same dropout draws for both
    got = step_terms(net, LOSS, batch)
    torch.manual_seed(5)
    transport, albedo, skin, light = net(_input(batch))
    want = LOSS({"transport": transport, "albedo": albedo, "skin": skin, "light": light}, batch)
    assert set(got) == set(want) and "albedo_anchor" not in got
    assert all(torch.equal(got[k], want[k]) for k in want)


def test_the_anchor_is_zero_at_the_warm_start_and_the_mean_albedo_change_over_the_person_after():
    net, batch = _net(), _batch()
    teacher = frozen_teacher(net, 3.0)
    net.eval()  # the student exactly as its teacher (no dropout, the same statistics)
    terms = step_terms(net, LOSS, batch, teacher, 3.0)
    assert float(terms["albedo_anchor"].detach()) == 0.0
    _nudge(net)
    terms = step_terms(net, LOSS, batch, teacher, 3.0)
    with torch.no_grad():
        moved, kept = net(_input(batch))[1], teacher(_input(batch))[1]
    person = batch["mask"][:, 0] > 0
    want = 3.0 * (moved - kept).abs().permute(1, 0, 2, 3)[:, person].mean()  # channels x person pixels
    assert float(terms["albedo_anchor"].detach()) == pytest.approx(float(want), rel=1e-5)
    assert float(want) > 1e-3  # it measures something
    others = {k: v for k, v in terms.items() if k not in ("albedo_anchor", "total")}
    total = float(sum(others.values()).detach() + terms["albedo_anchor"].detach())
    assert float(terms["total"].detach()) == pytest.approx(total, rel=1e-6)


def test_the_background_does_not_count():
    """A teacher whose albedo differs from the student's only off the person gives a zero anchor; one 0.1 off
    everywhere gives W · 0.1."""
    net, batch = _net(), _batch()
    net.eval()
    outside = batch["mask"] == 0

    def teacher_off(by_outside: float, by_inside: float):
        def teacher(x):
            with torch.no_grad():
                transport, albedo, skin, light = net(x)
            return transport, albedo + torch.where(outside, by_outside, by_inside), skin, light
        return teacher

    assert float(step_terms(net, LOSS, batch, teacher_off(0.7, 0.0), 2.0)["albedo_anchor"].detach()) == 0.0
    got = float(step_terms(net, LOSS, batch, teacher_off(0.7, 0.1), 2.0)["albedo_anchor"].detach())
    assert got == pytest.approx(0.2, rel=1e-4)


def test_its_gradient_reaches_the_albedo_path_only_and_never_the_teacher():
    """The albedo comes from the shared encoder, the albedo block ``rb`` and decoder ``b`` (whose last conv also
    makes the skin channel): the anchor moves those, never the transport decoder, its block ``ra``, the light head,
    the skin channel's own weights, or the frozen teacher."""
    net, batch = _net(), _batch()
    teacher = frozen_teacher(net, 2.0)
    _nudge(net)
    net.train()
    terms = step_terms(net, LOSS, batch, teacher, 2.0)
    terms["albedo_anchor"].backward()
    assert all(p.grad is None for p in teacher.parameters())
    grads = {name: p.grad for name, p in net.named_parameters()}

    def reached(name: str) -> bool:
        return grads[name] is not None and float(grads[name].abs().max()) > 0

    transport_side = [n for n in grads if n.startswith(("ra.", "dc0a", "dc1a", "dc2a", "dc3a", "dc4a", "dc5a",
                                                         "bndc0a", "bndc1a", "bndc2a", "bndc3a", "bndc4a"))]
    light_head = [n for n in grads if n.startswith(("c0l", "c1l", "c2l", "bnc0l", "bnc1l"))]
    assert transport_side and light_head and not any(reached(n) for n in transport_side + light_head)
    assert all(reached(n) for n in ("c0.weight", "c3.weight", "rb.c1.weight", "dc0b.weight", "dc5b.weight"))
    assert float(grads["dc5b.weight"][3].abs().max()) == 0.0 and float(grads["dc5b.bias"][3]) == 0.0  # skin
    assert float(grads["dc5b.weight"][:3].abs().max()) > 0.0


def test_a_step_moves_the_student_and_leaves_the_teacher_as_it_was():
    net, batch = _net(), _batch()
    teacher = frozen_teacher(net, 2.0)
    before = {k: v.clone() for k, v in teacher.state_dict().items()}
    _nudge(net)
    net.train()
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3)
    for _ in range(2):
        optimizer.zero_grad()
        step_terms(net, LOSS, batch, teacher, 2.0)["total"].backward()
        optimizer.step()
    assert not teacher.training
    assert all(torch.equal(before[k], v) for k, v in teacher.state_dict().items())  # running statistics included
    assert not torch.equal(teacher.dc5b.weight, net.dc5b.weight)


def test_a_heavier_anchor_keeps_the_albedo_nearer_the_warm_start():
    """A few steps on one batch whose truth albedo is far from the network's: the anchored run's albedo ends nearer
    the start's, the plain run's nearer the truth."""
    batch = _batch()
    x = _input(batch)
    drift = {}
    for weight in (0.0, 20.0):
        net = _net()
        teacher = frozen_teacher(_net(), 1.0)  # the same start, kept apart (also for W = 0, only to measure)
        optimizer = torch.optim.Adam(net.parameters(), lr=3e-3)
        net.train()
        for i in range(8):
            torch.manual_seed(i)
            optimizer.zero_grad()
            step_terms(net, LOSS, batch, frozen_teacher(net, 0.0) if weight == 0 else teacher, weight)[
                "total"].backward()
            optimizer.step()
        net.eval()
        with torch.no_grad():
            person = batch["mask"][:, 0] > 0
            drift[weight] = float((net(x)[1] - teacher(x)[1]).abs().permute(1, 0, 2, 3)[:, person].mean())
    assert drift[20.0] < 0.5 * drift[0.0]  # 0.017 against 0.055 when written
