"""The evaluation's figures: Figure 7 (predicted QE and PE per subject and condition) and Figure 6 (scan -> pinna
distances on the paper's colour scale, with their histograms), as PNG files written atomically."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from core.atomic import atomic_path


def figure7(rows: list[dict], path: str | os.PathLike) -> Path:
    """QE (%) and PE (deg) per subject and condition, side by side (the paper's Figure 7): first by the paper's
    protocol (``original`` as reference and template, where the rows have its columns), then with the dataset's
    HRIRs as reference and template."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    subjects = list(dict.fromkeys(r["subject"] for r in rows))
    conditions = list(dict.fromkeys(r["condition"] for r in rows))
    protocols = [("qe_percent", "pe_deg", "template: the dataset's HRIRs")]
    if any(r.get("qe_paper_percent") is not None for r in rows):
        protocols.insert(0, ("qe_paper_percent", "pe_paper_deg", "paper's protocol; template: original (solved here)"))
    width = 0.8 / len(conditions)
    legend_columns = min(len(conditions), 5)  # wider rows ran off the figure's edges
    legend_rows = -(-len(conditions) // legend_columns)
    height_in = 0.4 + 3.2 * len(protocols) + 0.22 * legend_rows
    fig, axes = plt.subplots(len(protocols), 2, figsize=(4.0 + 1.3 * len(subjects), height_in), squeeze=False)
    for (qe_key, pe_key, title), panels in zip(protocols, axes):
        for ax, key, label in ((panels[0], qe_key, "quadrant errors (%)"), (panels[1], pe_key, "local polar RMS error (deg)")):
            for k, condition in enumerate(conditions):
                values = [next((r[key] for r in rows if r["subject"] == s and r["condition"] == condition
                                and r.get(key) is not None), np.nan) for s in subjects]
                ax.bar(np.arange(len(subjects)) + (k - (len(conditions) - 1) / 2) * width, values, width,
                       label=condition)
            ax.set_xticks(np.arange(len(subjects)), subjects)
            ax.set_ylabel(label)
            ax.grid(axis="y", alpha=0.3)
            ax.set_title(title, fontsize=8)
    # one legend under all panels: inside a panel it hides the tallest bars
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=legend_columns, fontsize=8, frameon=False)
    fig.suptitle("predicted sagittal-plane localisation (baumgartner2014, S at 8 % QE on the template)", fontsize=9)
    fig.tight_layout(rect=(0, (0.1 + 0.22 * legend_rows) / height_in, 1, 1))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)
    return Path(path)


def figure6(results: str | os.PathLike, subjects: list[str], conditions: dict[str, list[str]],
            path: str | os.PathLike) -> Path:
    """Per subject: the target scan coloured by its distance to the aligned PPM on the paper's scale (<= 1 mm
    red, ~3.5 mm green, >= 5 mm blue), the same on a 0-1.5 mm scale (where a fit that is within 1 mm nearly
    everywhere still differs), and the histogram of the distances of every condition with medians (the paper's
    Figure 6, plus the fine-scale column)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    import trimesh  # noqa: PLC0415

    from ppm.render import FINE_SCALE, PAPER_SCALE, render_distance_map  # noqa: PLC0415

    results = Path(results)
    # one colour per condition in every subject's histogram
    every = list(dict.fromkeys(c for subject in subjects for c in conditions[subject]))
    colours = {c: plt.get_cmap("tab10")(k % 10) for k, c in enumerate(every)}
    fig, axes = plt.subplots(len(subjects), 3, figsize=(16, 3.3 * len(subjects)), squeeze=False,
                             gridspec_kw={"width_ratios": [2.0, 2.0, 1.0]})
    with tempfile.TemporaryDirectory() as tmp:
        for row, subject in enumerate(subjects):
            data = {c: np.load(results / subject / "evaluation" / c / "distances.npz")
                    for c in conditions[subject]}
            target = trimesh.load(results / subject / "target" / "pinna_target.ply", process=False, force="mesh")
            forward = data["ppm"]["target_to_model"]
            # the prepared target may have dropped outliers: then its points are shown
            whole = len(target.vertices) == len(forward)
            points, faces = (target.vertices, target.faces) if whole else (data["ppm"]["target_points_mm"], None)
            for column, scale in enumerate((PAPER_SCALE, FINE_SCALE)):
                picture = Path(tmp) / f"{subject}_{column}.png"
                render_distance_map(points, faces, forward, picture, f"{subject}: scan -> PPM, {scale.label}",
                                    scale=scale)
                axes[row, column].imshow(plt.imread(picture))
                axes[row, column].axis("off")
            ax = axes[row, 2]
            bins = np.linspace(0.0, 5.0, 51)
            for condition, values in data.items():
                d = values["target_to_model"]
                ax.hist(np.clip(d, 0, 5.0), bins=bins, weights=np.full(len(d), 100.0 / len(d)), histtype="step",
                        lw=1.2, color=colours[condition], label=f"{condition}: median {np.median(d):.2f} mm")
            ax.axvline(np.median(forward), color="k", ls="--", lw=0.8)
            ax.set_xlabel("distance scan -> pinna (mm; last bin >= 5)")
            ax.set_ylabel("scan points (%)")
            ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp_png:
        fig.savefig(tmp_png, dpi=100, format="png")
    plt.close(fig)
    return Path(path)
