"""Adaptive density control of 3DGS: clone, split, prune and opacity reset, with the optimiser's
Adam moments carried along so that training continues smoothly."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .float32 import F32
from .gaussians import GaussianModel
from .reference import quat_to_rotation


@dataclass
class DensifyConfig:
    # first and last iterations that densify, both rounds (3DGS's 500 and 15000 exclude theirs:
    # its rounds are 600..14900, 144 of them, start 501 and stop 14999 here)
    start: int = 500
    stop: int = 0  # 0: half the run (3DGS: 15k of 30k)
    every: int = 100  # densify and prune every this many iterations
    # mean screen-space gradient (NDC units) that triggers it, of the absolute per-pixel shares
    # with `absgrad` (AbsGS), else of the plain gradient (3DGS: 0.0002 over 144 densify rounds;
    # our 3000-iteration default has 11, at 500..1500 every 100, and half that threshold gained
    # 0.0-1.1 dB). AbsGS at 0.0002 gained SpikeGS another 0.8 dB on solids and 1.1 on
    # fine-texture (BENCHMARKS.md)
    grad_threshold: float = 0.0002
    # clone below this size (fraction of the scene radius), else split: 3DGS's 0.01 of the camera
    # extent, ~3 scene radii on our orbits (see lr.means)
    percent_dense: float = 0.03
    min_opacity: float = 0.005  # prune below
    # size pruning, as in 3DGS only after the first opacity reset (a run without one never prunes
    # by size): larger than this many pixels (0: never), larger (largest axis) than this fraction
    # of the scene radius (0: never). Our cameras sit at ~2.5 radii, so 0.1 is ~1/3 of 3DGS's
    # 0.1 of the camera extent; at 0.5, faint Gaussians of the views' background colour (harmless
    # to the loss) stayed and covered 60 % of a 256² render's tile pairs (BENCHMARKS.md)
    max_screen_size: float = 0.0
    max_world_size: float = 0.1
    # 3DGS resets every 3k of its 30k iterations; a 3000-iteration run resets once, at 1000
    opacity_reset_every: int = 1000  # 0: never
    max_gaussians: int = 200_000  # never grow beyond
    # AbsGS: select by the per-pixel shares of the screen-space gradient summed in absolute value,
    # which do not cancel over a Gaussian that straddles an edge or a texture; false: 3DGS's plain
    # gradient (then 0.0001 was our best threshold)
    absgrad: bool = True
    # the instant render's screen-space gradient alone, over its losses' weight, where a
    # method has both losses (false: the step's whole loss over its total weight, 1 + λ, which
    # counts the instant render a fifth and the exposure's smooth, blurred residuals the rest:
    # SpikeGS grew the fewest Gaussians). SpikeGS gained in 10 of 10 paired runs: +0.16 / +0.59 /
    # +0.33 dB on fine-texture / solids / wires at 128² over 3 seeds, +0.84 at 256²
    # (BENCHMARKS.md). An odd K's centre exposure pose shares the instant render, and λ/K of
    # the exposure's gradient with it; the signal is then over the larger of the two weights,
    # so that it stops growing with λ (BENCHMARKS.md, "The exposure loss in the densification
    # signal": rendered apart, SpikeGS lost 0.6-0.8 dB at 128²)
    instant_only: bool = True

    def first_iteration(self) -> int:
        """The first iteration that may densify: the first multiple of `every` from `start`."""
        return -(-max(self.start, 1) // self.every) * self.every

    def last_iteration(self, iterations: int) -> int:
        """The end of densification's window in a run of `iterations`: stop, or half the run
        (its rounds fall on the multiples of `every` from `first_iteration` up to it)."""
        return self.stop or iterations // 2

    def last_round(self, iterations: int) -> int:
        """The last iteration that densifies in a run of `iterations`, 0 where none does: the
        last multiple of `every` from `first_iteration` to `last_iteration`, not the run's last
        (`Densifier.step`)."""
        last = min(self.last_iteration(iterations), iterations - 1)
        rounds = range(self.first_iteration(), last + 1, self.every)
        return rounds[-1] if len(rounds) else 0


def _surgery(model: GaussianModel, optimizer: torch.optim.Optimizer, param_fn, state_fn) -> None:
    """Replace each Gaussian parameter p by param_fn(name, p), its Adam moments m by
    state_fn(name, m)."""
    for group in optimizer.param_groups:
        name = group["name"]
        if name not in model.params:
            continue
        old = group["params"][0]
        new = torch.nn.Parameter(param_fn(name, old.detach()))
        state = optimizer.state.pop(old, None)
        if state:
            state["exp_avg"] = state_fn(name, state["exp_avg"])
            state["exp_avg_sq"] = state_fn(name, state["exp_avg_sq"])
            optimizer.state[new] = state
        group["params"][0] = new
        model.params[name] = new


class Densifier:
    """Accumulates screen-space gradients between steps and applies density control."""

    def __init__(
        self,
        config: DensifyConfig,
        scene_radius: float,
        iterations: int,
        generator: torch.Generator | None = None,
    ):
        self.config = config
        # the splits' random offsets: the trainer's own generator (None: torch's global one),
        # so that other code drawing from torch's global RNG in the same process (a user's
        # on_eval callback, another run) does not change a run, nor a run the caller's numbers
        self.generator = generator
        self.scene_radius = scene_radius
        self.iterations = iterations  # of the whole run: no opacity reset too close to its end
        self.stop = config.last_iteration(iterations)
        # (float32 each, whatever torch's default dtype a caller set: float16 changed the run)
        self.grad_sum = torch.zeros(0, **F32)  # [N] summed NDC screen-gradient norms since a round
        self.count = torch.zeros(0, **F32)  # [N] steps each Gaussian was visible in
        self.max_radii = torch.zeros(0, **F32)  # [N] largest screen radius (pixels)
        self.pruned: dict[str, int] = {}  # the last round's: Gaussians each pruning setting removed
        self.strongest = 0.0  # the largest mean gradient a round has seen (inf: not recorded)
        self.capped = 0  # the most Gaussians over the threshold a round left for max_gaussians

    def _resize(self, n: int) -> None:
        if self.grad_sum.shape[0] != n:
            self.grad_sum, self.count, self.max_radii = (
                torch.zeros(n, **F32),
                torch.zeros(n, **F32),
                torch.zeros(n, **F32),
            )

    def observe(
        self, radii: torch.Tensor, screen_grad: torch.Tensor, width: int, height: int
    ) -> None:
        """Record a step's screen-space gradients [N, 2] (pixels; with `absgrad` the absolute
        per-pixel sums) for the Gaussians visible in it."""
        self._resize(radii.shape[0])
        visible = radii > 0  # selects by torch.where: boolean indexing took ~1 ms a step
        ndc = screen_grad * torch.tensor([0.5 * width, 0.5 * height], dtype=screen_grad.dtype)
        self.grad_sum += torch.where(visible, ndc.norm(dim=1), 0.0)
        self.count += visible
        self.max_radii = torch.maximum(self.max_radii, radii.float())  # radius 0 where hidden

    def step(self, model: GaussianModel, optimizer: torch.optim.Optimizer, iteration: int) -> None:
        """Densify/prune and reset opacities at the configured iterations (1-based); never at the
        run's last (3DGS densifies before `densify_until_iter`): its clones and splits would be
        saved untrained, and the run's last evaluation, taken before, would not be of the scene
        it saves."""
        c = self.config
        last = iteration >= self.iterations
        if c.start <= iteration <= self.stop and iteration % c.every == 0 and not last:
            self._densify_and_prune(model, optimizer, iteration)
        if self._resets_opacity(iteration):
            cap = torch.logit(torch.tensor(0.01, **F32))
            _surgery(
                model,
                optimizer,
                lambda name, p: torch.minimum(p, cap) if name == "opacity_logits" else p,
                lambda name, m: torch.zeros_like(m) if name == "opacity_logits" else m,
            )

    def _resets_opacity(self, iteration: int) -> bool:
        """Opacities are reset every `opacity_reset_every` iterations before `stop`, so that a
        pruning round follows where densification runs (3DGS and gsplat reset only while
        densifying, `iteration < densify_until_iter`, whatever its start: 3k..12k of 30k; a
        reset at `stop` was never pruned after), and only with a whole reset period left to
        recover from it; a reset at the end of a run would leave a nearly transparent scene."""
        every = self.config.opacity_reset_every
        return bool(
            every
            and iteration % every == 0
            and iteration < self.stop
            and iteration + every <= self.iterations
        )

    def _after_first_reset(self, iteration: int) -> bool:
        """Whether a first opacity reset happened before `iteration`: faint Gaussians have then had
        their chance to fade, and the initial ones (random ones can start larger than the size
        cap) a reset period to shrink or split."""
        every = self.config.opacity_reset_every
        return iteration > every and self._resets_opacity(every)  # every = 0: never

    def _densify_and_prune(self, model: GaussianModel, optimizer, iteration: int) -> None:
        c = self.config
        n = len(model)
        self._resize(n)
        grads = self.grad_sum / self.count.clamp_min(1)  # [N] mean over the visible steps
        self.strongest = max(self.strongest, float(grads.max()) if n else 0.0)
        selected = grads >= c.grad_threshold  # [N] bool
        room = max(c.max_gaussians - n, 0)
        if int(selected.sum()) > room:  # keep the strongest gradients under the cap
            self.capped = max(self.capped, int(selected.sum()) - room)
            order = torch.argsort(grads, descending=True)
            selected = torch.zeros(n, dtype=torch.bool)
            selected[order[:room]] = True
        big = model.scales.max(dim=1).values > c.percent_dense * self.scene_radius  # [N]
        clone, split = selected & ~big, selected & big  # [N] bool each; S = split.sum()

        with torch.no_grad():
            p = {k: v.detach() for k, v in model.params.items()}
            new = {k: v[clone] for k, v in p.items()}  # clones: exact copies
            # splits: two samples from each Gaussian, 1.6x smaller; the originals are removed
            std = model.scales[split].repeat(2, 1)  # [2S, 3]
            rot = quat_to_rotation(torch.nn.functional.normalize(p["quats"][split], dim=1)).repeat(
                2, 1, 1
            )  # [2S, 3, 3]
            noise = torch.randn(std.shape, generator=self.generator, dtype=std.dtype)
            offsets = (rot @ (noise * std).unsqueeze(-1)).squeeze(-1)  # [2S, 3]
            for k, v in p.items():
                extra = v[split].repeat(2, *([1] * (v.dim() - 1)))
                if k == "means":
                    extra = extra + offsets
                elif k == "log_scales":
                    extra = extra - torch.log(torch.tensor(1.6, **F32))
                new[k] = torch.cat([new[k], extra])
            added = new["means"].shape[0]  # clones + 2S
            _surgery(
                model,
                optimizer,
                lambda name, v: torch.cat([v, new[name]]),
                lambda name, m: torch.cat([m, torch.zeros_like(new[name])]),
            )
            remove = torch.cat([split, torch.zeros(added, dtype=torch.bool)])  # [N + added]
            pruned = {"min_opacity": model.opacities < c.min_opacity}  # [N + added] bool each
            if self._after_first_reset(iteration):
                if c.max_world_size:
                    size = model.scales.max(dim=1).values
                    pruned["max_world_size"] = size > c.max_world_size * self.scene_radius
                if c.max_screen_size:
                    radii = torch.cat([self.max_radii, torch.zeros(added, **F32)])
                    pruned["max_screen_size"] = radii > c.max_screen_size
            for mask in pruned.values():
                remove |= mask
            # what each setting pruned this round (a run pruned to nothing names those that did)
            self.pruned = {name: int(mask.sum()) for name, mask in pruned.items() if mask.any()}
            keep = ~remove
            _surgery(model, optimizer, lambda name, v: v[keep], lambda name, m: m[keep])
        self._resize(0)
        self._resize(len(model))

    def unreached(self, iteration: int) -> str | None:
        """What to say where every round up to `iteration`, the last among them, found no
        Gaussian's gradient at the threshold (the run kept its initial Gaussians, less those
        pruned), else None."""
        last = self.config.last_round(self.iterations)
        if not last or iteration < last or self.strongest >= self.config.grad_threshold:
            return None
        return (
            f"densification grew no Gaussian: the largest mean screen-space gradient its rounds "
            f"saw, {self.strongest:.3g}, is under densify.grad_threshold "
            f"{self.config.grad_threshold:g}, so the run kept its initial Gaussians (fewer "
            f"where pruned): lower the threshold under {self.strongest:.3g} where the renders "
            f"look coarse"
        )

    def capped_note(self) -> str | None:
        """What to say where a round left Gaussians over the threshold, neither cloned nor split,
        for densify.max_gaussians (a threshold far too low grew the model to the cap, unsaid),
        else None."""
        if not self.capped:
            return None
        return (
            f"densification reached densify.max_gaussians {self.config.max_gaussians:,}: a round "
            f"left up to {self.capped:,} Gaussians over densify.grad_threshold "
            f"{self.config.grad_threshold:g} as they were; raise the cap where memory allows, "
            f"or the threshold where so many was not meant (0.0002-0.0003 with absgrad)"
        )

    def state_dict(self) -> dict:
        return {
            "grad_sum": self.grad_sum,
            "count": self.count,
            "max_radii": self.max_radii,
            "strongest": self.strongest,
            "capped": self.capped,
        }

    def load_state_dict(self, state: dict) -> None:
        self.grad_sum, self.count, self.max_radii = (
            state["grad_sum"],
            state["count"],
            state["max_radii"],
        )
        self.strongest = state.get("strongest", float("inf"))  # an earlier version's: unknown
        self.capped = state.get("capped", 0)
