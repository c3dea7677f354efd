"""The paper's network: orientation in, 1 + 2K Fourier coefficients of the deviation curve out.

As section 2 of Gaska et al. describes it: input (A0 / 90, sin B0, cos B0), dense 256 -> 256 ->
128 with LayerNorm, GELU and dropout, a linear output of 1 + 2K coefficients (K = 8) whose curve
is compared with the measured one by a weighted Huber loss; AdamW, ReduceLROnPlateau and early
stopping, on disjoint (A, B) groups. The target is the mean curve by default (`target="mean"`).
Monte Carlo adds Gaussian touch noise with the pooled repetition sigma of the training rings.

Method: docs/methods/network.md.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Self

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from safetensors import safe_open
from safetensors.torch import load_file, save_file
from torch import nn

from ph_explorer import metrics
from ph_explorer.campaign import Campaign
from ph_explorer.harmonics import fourier_basis, remove_size_and_centre
from ph_explorer.models.deviation_model import DeviationModel, as_orientations, training_mask

FILE_NAME = "network.safetensors"
# Threads for training (the budget is 2 cores). The matrices are tiny (16 x 256): a second thread
# buys nothing and, on a shared machine, its spin-waiting made epochs 10-70x slower (measured
# 16 ms/epoch with 1 thread against 185-1100 ms with 2 on a loaded 2-core box).
MAX_THREADS = 1

# progress(epoch, train_loss, validation_mae_um, learning_rate)
ProgressCallback = Callable[[int, float, float, float], None]


@dataclass
class NetworkConfig:
    """Hyperparameters (the paper's where it gives them)."""

    k_max: int = 8
    hidden: tuple[int, ...] = (256, 256, 128)
    dropout: float = 0.10
    learning_rate: float = 1e-3
    weight_decay: float = 1e-4
    l2: float = 1e-4
    min_learning_rate: float = 1e-6
    lr_factor: float = 0.5
    lr_patience: int = 40  # epochs without a better validation MAE before the lr is halved
    early_stopping_patience: int = 200  # epochs without a better validation MAE before stopping
    max_epochs: int = 2000
    batch_size: int = 16  # samples (orientations, or repetitions) per step
    validation_fraction: float = 0.12
    target: str = "mean"  # "mean" or "repetitions"
    huber_sigmas: float = 2.0  # Huber threshold in noise sigmas of the target
    seed: int = 0

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["hidden"] = list(self.hidden)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> NetworkConfig:
        known = {k: v for k, v in d.items() if k in cls.__dataclass_fields__}
        if "hidden" in known:
            known["hidden"] = tuple(int(h) for h in known["hidden"])
        return cls(**known)


def encode_orientations(orientations: NDArray[np.float64]) -> NDArray[np.float32]:
    """(m, 3) network input: A0 / 90 and B0 on the unit circle (B0 = -180 and 180 coincide)."""
    a, b = orientations[:, 0], np.radians(orientations[:, 1])
    return np.column_stack([a / 90.0, np.sin(b), np.cos(b)]).astype(np.float32)


class FourierMLP(nn.Module):
    """Dense blocks (Linear, LayerNorm, GELU, dropout on the first two) and a linear Fourier head."""

    def __init__(self, config: NetworkConfig, n_inputs: int = 3):
        super().__init__()
        layers: list[nn.Module] = []
        width = n_inputs
        for i, h in enumerate(config.hidden):
            layers += [nn.Linear(width, h), nn.LayerNorm(h), nn.GELU()]
            if i < len(config.hidden) - 1:
                layers.append(nn.Dropout(config.dropout))
            width = h
        self.body = nn.Sequential(*layers)
        self.head = nn.Linear(width, 1 + 2 * config.k_max)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(x))

    def dense_weights(self) -> list[torch.Tensor]:
        return [m.weight for m in self.body if isinstance(m, nn.Linear)]


@dataclass
class TrainingLog:
    """What a fit did: epochs, best epoch, time, per-epoch validation MAE, curve-level diagnostics."""

    epochs: int = 0
    best_epoch: int = 0
    seconds: float = 0.0
    validation_mae_um: list[float] = field(default_factory=list)
    diagnostics: dict[str, dict[str, float]] = field(default_factory=dict)
    validation_orientations: list[list[float]] = field(default_factory=list)


class FourierNetwork(DeviationModel):
    """The paper's Fourier-output network (torch)."""

    name = "network"

    def __init__(self, config: NetworkConfig | None = None, progress: ProgressCallback | None = None, **overrides: Any):
        base = config or NetworkConfig()
        self.config = NetworkConfig.from_dict({**base.as_dict(), **overrides}) if overrides else base
        self.progress = progress
        self.module: FourierMLP | None = None
        self.scale_um = 1.0
        self.sigma_um = 0.0
        self.n_points = 64
        self.log = TrainingLog()

    # -- learning --------------------------------------------------------------------------------
    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        cfg = self.config
        if cfg.target not in ("mean", "repetitions"):
            raise ValueError("target must be 'mean' or 'repetitions'")
        mask = training_mask(campaign, train)
        usable = np.flatnonzero(mask)
        if usable.size < 2:
            raise ValueError("the network needs at least two training orientations")
        rng = np.random.default_rng(cfg.seed)
        n_val = int(round(cfg.validation_fraction * usable.size))
        n_val = min(max(n_val, 1), usable.size - 1)
        val_idx = np.sort(rng.choice(usable, n_val, replace=False))
        fit_idx = np.setdiff1d(usable, val_idx)

        n_rep, n_pt = campaign.n_repetitions, campaign.n_points
        sigma_o = campaign.repetition_sigma().mean(axis=1) if n_rep > 1 else np.zeros(campaign.n_orientations)
        pooled = float(np.sqrt(np.mean(sigma_o[usable] ** 2))) if n_rep > 1 else 0.0
        means = campaign.mean_curves()
        self.n_points = n_pt
        self.sigma_um = pooled
        self.scale_um = float(np.sqrt(np.mean(means[fit_idx] ** 2))) or 1.0

        # Samples: (input, target curve, weight) per orientation or per repetition.
        if cfg.target == "mean":
            x_fit, y_fit = campaign.orientations[fit_idx], means[fit_idx]
            target_sigma = pooled / np.sqrt(n_rep)
            spread = sigma_o[fit_idx]
        else:
            x_fit = np.repeat(campaign.orientations[fit_idx], n_rep, axis=0)
            y_fit = campaign.deviations[fit_idx].reshape(-1, n_pt)
            target_sigma = pooled
            spread = np.repeat(sigma_o[fit_idx], n_rep)
        weights = inverse_variance_weights(spread, pooled)
        # Without repetitions there is no noise scale: the Huber loss is then quadratic up to the
        # curves' own RMS.
        delta = cfg.huber_sigmas * target_sigma / self.scale_um if pooled > 0 else 1.0

        previous_threads = torch.get_num_threads()
        previous_deterministic = torch.are_deterministic_algorithms_enabled()
        torch.set_num_threads(min(MAX_THREADS, previous_threads))
        torch.use_deterministic_algorithms(True)
        try:
            torch.manual_seed(cfg.seed)
            self.module = FourierMLP(cfg)
            self._train(
                torch.from_numpy(encode_orientations(x_fit)),
                torch.from_numpy((y_fit / self.scale_um).astype(np.float32)),
                torch.from_numpy(weights.astype(np.float32)),
                torch.from_numpy(encode_orientations(campaign.orientations[val_idx])),
                means[val_idx],
                delta,
            )
        finally:
            torch.set_num_threads(previous_threads)
            torch.use_deterministic_algorithms(previous_deterministic)
        self.log.validation_orientations = campaign.orientations[val_idx].tolist()
        self.log.diagnostics = {
            "train": curve_metrics(self.predict(campaign.orientations[fit_idx]), campaign.deviations[fit_idx]),
            "validation": curve_metrics(self.predict(campaign.orientations[val_idx]), campaign.deviations[val_idx]),
        }
        return self

    def _train(
        self,
        x: torch.Tensor,
        y: torch.Tensor,
        w: torch.Tensor,
        x_val: torch.Tensor,
        y_val_um: NDArray[np.float64],
        delta: float,
    ) -> None:
        cfg, module = self.config, self.module
        assert module is not None
        basis = torch.from_numpy(fourier_basis(y.shape[1], cfg.k_max).T.astype(np.float32))  # (1+2K, N)
        # foreach: one call per step for all the tensors, not one per tensor (torch's CPU default):
        # the same weights to the bit, a third less time for this small a network.
        optimiser = torch.optim.AdamW(module.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay, foreach=True)
        scheduler = torch.optim.lr_scheduler.ReduceLROnPlateau(
            optimiser, mode="min", factor=cfg.lr_factor, patience=cfg.lr_patience, min_lr=cfg.min_learning_rate
        )
        huber = nn.HuberLoss(reduction="none", delta=delta)
        generator = torch.Generator().manual_seed(cfg.seed)
        best_mae, best_state, best_epoch = float("inf"), None, 0
        log = TrainingLog()
        start = time.perf_counter()
        n = x.shape[0]
        for epoch in range(1, cfg.max_epochs + 1):
            module.train()
            order = torch.randperm(n, generator=generator)
            total = 0.0
            for batch in order.split(cfg.batch_size):
                curve = module(x[batch]) @ basis  # d'(n) from the Fourier coefficients
                data_loss = (huber(curve, y[batch]).mean(dim=1) * w[batch]).sum() / w[batch].sum()
                l2 = sum((p**2).sum() for p in module.dense_weights())
                loss = data_loss + cfg.l2 * l2
                optimiser.zero_grad(set_to_none=True)
                loss.backward()
                optimiser.step()
                total += float(data_loss.detach()) * len(batch)
            module.eval()
            with torch.no_grad():
                val_curves = (module(x_val) @ basis).numpy().astype(float) * self.scale_um
            val_mae = float(np.abs(val_curves - y_val_um).mean())
            scheduler.step(val_mae)
            log.validation_mae_um.append(val_mae)
            if val_mae < best_mae - 1e-6:
                best_mae, best_epoch = val_mae, epoch
                best_state = {k: v.detach().clone() for k, v in module.state_dict().items()}
            if self.progress is not None:
                self.progress(epoch, total / n, val_mae, optimiser.param_groups[0]["lr"])
            if epoch - best_epoch >= cfg.early_stopping_patience:
                break
        if best_state is not None:
            module.load_state_dict(best_state)  # restore the best validation weights
        module.eval()
        log.epochs, log.best_epoch, log.seconds = epoch, best_epoch, time.perf_counter() - start
        self.log = log

    # -- prediction ------------------------------------------------------------------------------
    def coefficients(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, 1 + 2K) Fourier coefficients in um: a0, a1, b1, ..., aK, bK."""
        if self.module is None:
            raise RuntimeError("the network is not fitted")
        o = as_orientations(orientations)
        self.module.eval()
        with torch.no_grad():
            out = self.module(torch.from_numpy(encode_orientations(o)))
        return out.numpy().astype(float) * self.scale_um

    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        n = self.n_points if n_points is None else int(n_points)
        curves = self.coefficients(orientations) @ fourier_basis(n, self.config.k_max).T
        # a0, a1, b1 are ~0 by construction (the targets are post-fit curves); remove them exactly.
        return remove_size_and_centre(curves)

    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        m = as_orientations(orientations).shape[0]
        return np.full((m, self.n_points if n_points is None else int(n_points)), self.sigma_um)

    # -- files ---------------------------------------------------------------------------------
    def save(self, directory: str | Path) -> Path:
        if self.module is None:
            raise RuntimeError("the network is not fitted")
        path = Path(directory) / FILE_NAME
        path.parent.mkdir(parents=True, exist_ok=True)
        metadata = {
            "config": json.dumps(self.config.as_dict()),
            "scale_um": repr(self.scale_um),
            "sigma_um": repr(self.sigma_um),
            "n_points": str(self.n_points),
        }
        state = {k: v.detach().contiguous() for k, v in self.module.state_dict().items()}
        save_file(state, str(path), metadata=metadata)
        return path

    @classmethod
    def load(cls, directory: str | Path) -> Self:
        path = Path(directory) / FILE_NAME
        with safe_open(str(path), framework="pt") as handle:
            metadata = handle.metadata()
        model = cls(NetworkConfig.from_dict(json.loads(metadata["config"])))
        model.scale_um = float(metadata["scale_um"])
        model.sigma_um = float(metadata["sigma_um"])
        model.n_points = int(metadata["n_points"])
        model.module = FourierMLP(model.config)
        model.module.load_state_dict(load_file(str(path)))
        model.module.eval()
        return model


def inverse_variance_weights(spread: NDArray[np.float64], pooled: float) -> NDArray[np.float64]:
    """Per-sample weights 1 / sigma^2, sigma shrunk halfway (in variance) to the pooled one, mean 1."""
    if pooled <= 0:
        return np.ones_like(spread)
    variance = 0.5 * spread**2 + 0.5 * pooled**2
    w = 1.0 / variance
    return w / w.mean()


def curve_metrics(predicted: NDArray[np.float64], deviations: NDArray[np.float64]) -> dict[str, float]:
    """Curve-level MAE and RMSE (um) of predicted curves (m, N) against the repetition mean and single ones."""
    if predicted.size == 0:
        return {}
    mae = metrics.mae(predicted, deviations)
    eps_mean = predicted - deviations.mean(axis=1)
    eps_single = predicted[:, None, :] - deviations
    return {
        "mae_mean_um": mae["mean"],
        "rmse_mean_um": float(np.sqrt((eps_mean**2).mean())),
        "mae_single_um": mae["single"],
        "rmse_single_um": float(np.sqrt((eps_single**2).mean())),
    }
