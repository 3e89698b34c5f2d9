"""Figures of a subject's evaluation: parameter deviations from the default PPM grouped as in the
paper's Figure 5 (locations mm, rotations deg, scales, shape keys) and the one-sided distance
distribution (scan -> aligned PPM, mm) with its median."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from core.atomic import atomic_path  # noqa: E402
from ppm.parameters import PinnaParameters, parameter_specs  # noqa: E402

GROUPS = (("location", "location (mm)"), ("rotation", "rotation (deg)"), ("scale", "scale (factor - 1)"),
          ("shape_key", "shape key (weight)"))


def group_indices(kind: str) -> list[int]:
    """Indices (in parameter-vector order) of the parameters of one GROUPS kind."""
    return [i for i, spec in enumerate(parameter_specs()) if spec.kind == kind]


def _save(fig, path: str | os.PathLike) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=Path(path).suffix.lstrip(".") or "png")
    plt.close(fig)
    return Path(path)


def parameter_deviation_figure(parameters: dict[str, PinnaParameters], path: str | os.PathLike,
                               title: str = "") -> Path:
    """Deviation from default per parameter group; one column of points per subject (several subjects
    side by side for a dataset)."""
    specs = parameter_specs()
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.6))
    names = list(parameters)
    for ax, (kind, label) in zip(axes, GROUPS):
        chosen = group_indices(kind)
        for k, name in enumerate(names):
            deviation = parameters[name].to_vector()[chosen] - np.array([specs[i].default for i in chosen])
            jitter = np.random.default_rng(k).uniform(-0.15, 0.15, len(chosen))
            ax.scatter(np.full(len(chosen), k) + jitter, deviation, s=10, alpha=0.7)
            ax.boxplot([deviation], positions=[k], widths=0.5, showfliers=False)
        ax.axhline(0, color="grey", lw=0.6)
        ax.set_xticks(range(len(names)), names, rotation=30 if len(names) > 3 else 0, fontsize=8)
        ax.set_title(f"{label}: {len(chosen)}", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title or "PPM parameter deviations from the default", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def distance_histogram(distances_mm: dict[str, np.ndarray], path: str | os.PathLike, title: str = "") -> Path:
    """Histogram (share of points) of the one-sided distances, with each median marked."""
    fig, ax = plt.subplots(figsize=(6, 3.4))
    upper = max(3.0, max(float(np.percentile(d, 99)) for d in distances_mm.values()))
    bins = np.linspace(0, upper, 60)
    for name, distance in distances_mm.items():
        weights = np.full(len(distance), 100.0 / len(distance))
        ax.hist(distance, bins=bins, weights=weights, histtype="step", lw=1.2,
                label=f"{name}: median {np.median(distance):.2f} mm")
        ax.axvline(np.median(distance), ls="--", lw=0.8)
    ax.set_xlabel("distance scan -> aligned PPM (mm)")
    ax.set_ylabel("points (%)")
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def localisation_bars(rows: list[dict], path: str | os.PathLike, title: str = "") -> Path:
    """Quadrant error rate (%) and local polar RMS error (deg) per subject, reference HRTFs next to PPM
    HRTFs (the paper's Figure 7 for a dataset). ``rows`` hold subject, qe/pe_reference, qe/pe_ppm."""
    rows = [r for r in rows if r.get("qe_ppm_percent") is not None]
    x = np.arange(len(rows))
    fig, axes = plt.subplots(1, 2, figsize=(3.0 + 0.9 * len(rows), 3.4))
    for ax, (metric, label) in zip(axes, (("qe", "quadrant errors (%)"), ("pe", "local polar RMS error (deg)"))):
        unit = "percent" if metric == "qe" else "deg"
        ax.bar(x - 0.2, [r[f"{metric}_reference_{unit}"] for r in rows], 0.4, label="reference")
        ax.bar(x + 0.2, [r[f"{metric}_ppm_{unit}"] for r in rows], 0.4, label="PPM")
        ax.set_xticks(x, [r["subject"] for r in rows], rotation=30 if len(rows) > 4 else 0, fontsize=8)
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title or "predicted localisation: reference vs PPM HRTFs", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def parameter_recovery_figure(truth: PinnaParameters, fitted: PinnaParameters, path: str | os.PathLike,
                              title: str = "") -> Path:
    """Fitted against true deviation from default, one panel per parameter group (locations mm, rotations
    deg, scales, shape keys), with the identity line: points on it are recovered exactly."""
    specs = parameter_specs()
    default = np.array([s.default for s in specs])
    true_dev, fitted_dev = truth.to_vector() - default, fitted.to_vector() - default
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.6))
    for ax, (kind, label) in zip(axes, GROUPS):
        chosen = group_indices(kind)
        x, y = true_dev[chosen], fitted_dev[chosen]
        limit = max(float(np.abs(np.concatenate([x, y])).max()), 1e-6) * 1.1
        ax.plot([-limit, limit], [-limit, limit], color="grey", lw=0.8)
        ax.scatter(x, y, s=12, alpha=0.8)
        ax.set_xlim(-limit, limit)
        ax.set_ylim(-limit, limit)
        ax.set_aspect("equal")
        ax.set_xlabel("true", fontsize=8)
        ax.set_ylabel("fitted", fontsize=8)
        ax.set_title(f"{label}: {len(chosen)}", fontsize=9)
        ax.grid(alpha=0.3)
    fig.suptitle(title or "parameter recovery: fitted vs true deviation from the default", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)
