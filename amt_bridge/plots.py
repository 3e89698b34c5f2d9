"""Figures of the localisation model: the prediction matrix (response vs target polar angle, as AMT's
plot_baumgartner2014) and quadrant-error / polar-error bars of several conditions side by side."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from core.atomic import atomic_path  # noqa: E402

from .model import PlanePrediction, Prediction  # noqa: E402


def draw_prediction_matrix(ax, plane: PlanePrediction, title: str | None = None) -> None:
    """Probability of each response angle (rows) for each target angle (columns) of one plane."""
    targets, responses = plane.target_polar_deg, plane.response_polar_deg
    edges_t = np.concatenate([[targets[0] - 2.5], (targets[1:] + targets[:-1]) / 2, [targets[-1] + 2.5]])
    edges_r = np.concatenate([[responses[0] - 2.5], (responses[1:] + responses[:-1]) / 2, [responses[-1] + 2.5]])
    mesh = ax.pcolormesh(edges_t, edges_r, plane.p, cmap="Greys", vmin=0, vmax=max(0.1, float(plane.p.max())))
    ax.plot([-90, 270], [-90, 270], color="tab:red", lw=0.6, alpha=0.6)
    ax.set_xlim(edges_t[0], edges_t[-1])
    ax.set_ylim(-90, 270)
    ax.set_xlabel("target polar angle (deg)")
    ax.set_ylabel("response polar angle (deg)")
    perf = plane.performance
    ax.set_title(title or f"lateral {plane.lateral_deg:+.0f}°: QE {perf.qe_percent:.1f} %, PE {perf.pe_deg:.1f}°",
                 fontsize=9)
    ax.figure.colorbar(mesh, ax=ax, label="probability")


def save_prediction_matrices(prediction: Prediction, path: str | os.PathLike, title: str = "") -> Path:
    """One panel per lateral plane, written atomically (PNG or PDF by suffix)."""
    planes = prediction.planes
    fig, axes = plt.subplots(1, len(planes), figsize=(4.2 * len(planes), 3.8), squeeze=False)
    for ax, plane in zip(axes[0], planes):
        draw_prediction_matrix(ax, plane)
    fig.suptitle(f"{title} (S = {prediction.sensitivity_db:.3f} dB)".strip(), fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format=Path(path).suffix.lstrip(".") or "png")
    plt.close(fig)
    return Path(path)


def save_error_bars(predictions: dict[str, Prediction], path: str | os.PathLike, title: str = "") -> Path:
    """Quadrant error rate (%) and local polar RMS error (deg) of each condition, side by side."""
    names = list(predictions)
    fig, (ax_qe, ax_pe) = plt.subplots(1, 2, figsize=(2.0 + 1.3 * len(names), 3.4))
    colours = plt.cm.tab10(np.arange(len(names)) % 10)
    ax_qe.bar(names, [predictions[n].qe for n in names], color=colours)
    ax_pe.bar(names, [predictions[n].pe for n in names], color=colours)
    ax_qe.set_ylabel("quadrant errors (%)")
    ax_pe.set_ylabel("local polar RMS error (deg)")
    for ax in (ax_qe, ax_pe):
        ax.tick_params(axis="x", rotation=20)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format=Path(path).suffix.lstrip(".") or "png")
    plt.close(fig)
    return Path(path)
