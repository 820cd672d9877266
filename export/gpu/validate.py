"""People held out of a ``gpu-train`` run: a fixed validation set, its loss, and the best weights so far.

The first lend's run trained 7,450 steps on 48 bank people and came back relighting them far better and people it
had never seen no better (worse on the held-out table's four), with nothing inside the run to tell (docs/GPU.md,
"What the first lend taught"). Here the last ``--val-people``
people of the bank (in its order, so every run holds out the same ones) are never trained on; ``--val-samples``
samples of them are rendered once at the start with fixed seeds (person, framing of the mix in turn, turn, light:
all drawn from ``--seed``, none flipped). Two figures are measured before the first step and then every
``--val-every`` seconds, network in eval mode: the training loss, and the relit RMSE (Â ⊙ max(0, T̂·l') against
a ⊙ max(0, t·l') under a second light l' of each sample, both clipped to [0, 1], in the mask). The weights of
the lowest ``--val-metric`` (the relit RMSE by default: the first lend's run lowered the loss on new people
without relighting them any better) are kept, on the device and in ``best.pt``, and are the ones exported: a
run whose training only overfits exports the weights it started from.
"""

from __future__ import annotations

import math

import numpy as np

from relight_rt import RelightError


def split_people(names: list[str], val_people: int) -> tuple[list[str], list[str]]:
    """(trained, held out): the last ``val_people`` names are held out; at least one is trained on."""
    if not 0 <= val_people < len(names):
        raise RelightError(f"--val-people {val_people}: the bank has {len(names)} people and at least one must be "
                           f"trained on (expected 0 to {len(names) - 1})")
    cut = len(names) - val_people
    return list(names[:cut]), list(names[cut:])


class HeldOut:
    """Validation samples of held-out people, rendered once on the training device.

    Args:
        subjects: the held-out DeviceSubjects.
        lights: (M, 9, 3) tensor of training lights on the device.
        settings: the run's RenderSettings.
        framings: framing names of the mix; sample i has framing ``framings[i % len(framings)]``.
        n: number of samples; sample i shows subject ``i % len(subjects)``.
        max_yaw: largest turn, degrees.
        seed: the run's seed (every random draw of the set comes from it).
    """

    def __init__(self, subjects: list, lights, settings, framings: list[str], n: int, max_yaw: float, seed: int):
        import torch

        from .render import pack, render_sample

        rng = np.random.default_rng([seed, 0x7A1])
        device = lights.device
        data, light_index, other_index = [], [], []
        self.names = [s.name for s in subjects]
        with torch.no_grad():
            for i in range(n):
                yaw = float(rng.uniform(-max_yaw, max_yaw))
                light_index.append(int(rng.integers(len(lights))))
                other_index.append(int(rng.integers(len(lights))))
                s = render_sample(subjects[i % len(subjects)], settings, framing=framings[i % len(framings)],
                                  yaw_deg=yaw, generator=torch.Generator().manual_seed(seed * 1_000_003 + i))
                data.append(pack(s).to(torch.float16))
        self.data = torch.stack(data)
        self.lights = lights[torch.as_tensor(light_index, device=device)]
        self.others = lights[torch.as_tensor(other_index, device=device)]

    def __len__(self) -> int:
        return len(self.data)

    def measure(self, model, loss_fn, batch_size: int, amp: bool) -> dict[str, float]:
        """{"loss": mean training loss, "relit_rmse": mean relit RMSE} over the samples (module doc), ``model`` in
        eval mode (its mode is restored)."""
        import torch

        from export.shading import shading
        from export.torch_data import render_input
        from export.training import autocast

        from .render import unpack

        was_training = model.training
        model.eval()
        total = relit = 0.0
        try:
            with torch.no_grad():
                for s in range(0, len(self.data), batch_size):
                    x = self.data[s : s + batch_size].float()
                    batch = {**unpack(x), "light": self.lights[s : s + batch_size]}
                    with autocast(x.device, amp):
                        t, a, k, light = model((2.0 * render_input(batch) - 1.0) * batch["mask"])
                        terms = loss_fn({"transport": t, "albedo": a, "skin": k, "light": light}, batch)
                    total += float(terms["total"]) * len(x)
                    other = self.others[s : s + batch_size]
                    ours = (a.float() * shading(t.float(), other)).clamp(0.0, 1.0)
                    truth = (batch["albedo"] * shading(batch["transport"], other)).clamp(0.0, 1.0)
                    m = batch["mask"]
                    err = ((ours - truth) ** 2 * m).sum((1, 2, 3)) / (3.0 * m.sum((1, 2, 3))).clamp_min(1.0)
                    relit += float(err.sqrt().sum())
        finally:
            model.train(was_training)
        return {"loss": total / len(self.data), "relit_rmse": relit / len(self.data)}


class Best:
    """The lowest validation loss so far and a copy of the weights that reached it."""

    def __init__(self):
        self.loss = math.inf
        self.step: int | None = None
        self.rendered = 0
        self.state: dict | None = None
        self.first: float | None = None
        self.last: float | None = None
        self.last_step: int | None = None
        self.checks = 0

    def offer(self, model, step: int, loss: float, rendered: int = 0) -> bool:
        """Record a validation; keep the weights when ``loss`` is the lowest so far, with ``rendered`` (the samples
        rendered until then, named in the exported graph's metadata). Returns whether it was."""
        self.checks += 1
        self.last, self.last_step = loss, step
        if self.first is None:
            self.first = loss
        if not (math.isfinite(loss) and loss < self.loss):
            return False
        self.loss, self.step, self.rendered = loss, step, rendered
        self.state = {k: v.detach().clone() for k, v in model.state_dict().items()}
        return True

    def summary(self) -> dict:
        return {"first": self.first, "best": None if self.step is None else self.loss, "best_step": self.step,
                "last": self.last, "last_step": self.last_step, "checks": self.checks}
