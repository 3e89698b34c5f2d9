"""A new listener's report: the head frame found, both PPM fits, the HRTFs in three sagittal planes, and what
personalising buys by baumgartner2014.

Localisation: the listener's own set is the template, with S calibrated so that it heard through itself gives 8 %
quadrant errors; each other set (other listeners of the run, and the sets of config ``listener.comparison_sets``,
e.g. SONICOM's, and measured dummy heads and listeners as in the evaluation's ``nonindividual``) is then a
non-individual HRTF heard with that template. The gain of personalising is their QE and PE minus the own set's.
Other sets are sampled at the listener's solved frequencies (exact DFT at their own rate) and rebuilt at the own
set's rate and length (:func:`reporting.nonindividual.rebuilt_like`), so a set measured at 44.1 kHz is resampled
too; each comparison is made on the directions the two sets share (:func:`amt_bridge.hrtf_set.on_common_directions`),
with S calibrated to 8 % on the own set at those directions, as the quadrant error depends on the grid's density.
The report ranks them, as the evaluation's ranking does (:mod:`reporting.ranking`).
"""
from __future__ import annotations

import html
import json
import os
from pathlib import Path

import numpy as np

from core.atomic import atomic_path, write_text_atomic

#: Lateral angles (deg) of the sagittal planes drawn and read by the model, as in the evaluation.
LATERAL_ANGLES_DEG = (-20.0, 0.0, 20.0)
QE_CALIBRATION_PERCENT = 8.0


def listener_localisation(own_hrtf: str | os.PathLike, others: dict[str, str | os.PathLike | dict],
                          calibration_grid: str | os.PathLike | None = None) -> dict:
    """QE/PE of the own set (``own_hrtf``: the listener's both-ear HRTF SOFA) as its own template at S for 8 %
    QE, and of each other set (name -> a SOFA file, HRIR or HRTF, or {file, kind[, sampling_rate_hz]} as
    :class:`reporting.nonindividual.MeasuredSet` reads it) with the own template at that S. With
    ``calibration_grid`` (a SOFA file, config listener.dataset_grid, whose directions the own set was solved on too),
    the headline S is calibrated on those directions: a dataset's grid, as the evaluation calibrates, instead of the
    denser full grid, on which the same QE needs a far sharper listener."""
    import sofar  # noqa: PLC0415

    from amt_bridge.hrtf_set import on_common_directions, read_hrtf_set  # noqa: PLC0415
    from amt_bridge.model import LocalisationModel  # noqa: PLC0415

    from .nonindividual import MeasuredSet, read_measured_set, rebuilt_like  # noqa: PLC0415

    frequencies = np.asarray(sofar.read_sofa(str(own_hrtf), verify=False, verbose=False).N)
    own = read_hrtf_set(own_hrtf)
    # the own set on the dataset's directions (it was solved on them too), else on all of its own
    calibrated_on = on_common_directions(own, read_hrtf_set(calibration_grid), 0.1)[0] if calibration_grid else own
    model = LocalisationModel(calibrated_on, calibrated_on, list(LATERAL_ANGLES_DEG))
    sensitivity = model.calibrate(QE_CALIBRATION_PERCENT, closest=True)
    reference = model.predict(sensitivity).as_dict()
    rows = {"own": {"qe_percent": reference["qe_percent"], "pe_deg": reference["pe_deg"],
                    "directions": int(calibrated_on.irs.shape[0]), "sensitivity_db": sensitivity}}
    for name, given in others.items():
        entry = given if isinstance(given, dict) else {"file": str(given), "kind": "other person"}
        measured = MeasuredSet.from_config({"name": name, **entry})
        own_there, other = on_common_directions(own, rebuilt_like(read_measured_set(measured), frequencies, own))
        template = LocalisationModel(own_there, own_there, list(LATERAL_ANGLES_DEG))
        there = template.calibrate(QE_CALIBRATION_PERCENT, closest=True)
        base = template.predict(there).as_dict()
        predicted = LocalisationModel(other, own_there, list(LATERAL_ANGLES_DEG)).predict(there).as_dict()
        rows[name] = {"qe_percent": predicted["qe_percent"], "pe_deg": predicted["pe_deg"],
                      "gain_qe_pp": predicted["qe_percent"] - base["qe_percent"],
                      "gain_pe_deg": predicted["pe_deg"] - base["pe_deg"], "directions": int(other.irs.shape[0]),
                      "sensitivity_db": there, "kind": measured.kind}
    return {"sensitivity_db": sensitivity, "calibration_qe_percent": QE_CALIBRATION_PERCENT, "sets": rows}


def plot_planes(hrtf_sofa: str | os.PathLike, out_png: str | os.PathLike, title: str) -> None:
    """Magnitude (dB) over polar angle and frequency in the sagittal planes at -20, 0 and 20 deg lateral, left
    and right ear (the directions within 2.5 deg of each plane)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    import sofar  # noqa: PLC0415

    from amt_bridge.angles import spherical_to_horizontal_polar  # noqa: PLC0415

    sofa = sofar.read_sofa(str(hrtf_sofa), verify=False)
    spectra = np.asarray(sofa.Data_Real) + 1j * np.asarray(sofa.Data_Imag)
    frequencies = np.asarray(sofa.N)
    positions = np.asarray(sofa.SourcePosition)
    lateral, polar = spherical_to_horizontal_polar(positions[:, 0], positions[:, 1])
    figure, axes = plt.subplots(2, 3, figsize=(12, 6.5), sharex=True, sharey=True, constrained_layout=True)
    image = None
    for column, angle in enumerate(LATERAL_ANGLES_DEG):
        chosen = np.flatnonzero(np.abs(lateral - angle) < 2.5)
        order = chosen[np.argsort(polar[chosen])]
        for row, ear in enumerate(("left", "right")):
            level = 20 * np.log10(np.maximum(np.abs(spectra[order, row, :]), 1e-12))
            image = axes[row, column].pcolormesh(frequencies / 1000.0, polar[order], level, shading="nearest",
                                                 cmap="viridis", vmin=-30, vmax=15)
            axes[row, column].set_title(f"{ear} ear, lateral {angle:+.0f}°", fontsize=10)
    for axis in axes[-1]:
        axis.set_xlabel("frequency (kHz)")
    for axis in axes[:, 0]:
        axis.set_ylabel("polar angle (°; 0 front, 90 up)")
    figure.colorbar(image, ax=axes, label="magnitude (dB re free field at the interaural centre)")
    figure.suptitle(title)
    with atomic_path(out_png) as tmp:
        figure.savefig(tmp, dpi=110, format="png")
    plt.close(figure)


def _fit_distances(summary_json: Path) -> dict:
    """Scan -> pinna distances (median_mm, p95_mm, ...) of a fit's summary: an alignment's
    (``distance_target_to_ppm``) or a personal-detail layer's (``ppm_detail``)."""
    summary = json.loads(summary_json.read_text())
    return summary["ppm_detail"] if "ppm_detail" in summary else summary["distance_target_to_ppm"]


def _coverage_html(coverage: dict[str, list[dict]] | None) -> str:
    """The page's section on what each ear's scan saw (:mod:`reporting.coverage`), with its advice."""
    if not coverage:
        return ""
    from .coverage import SEEN_MM, coverage_advice  # noqa: PLC0415

    regions = list(dict.fromkeys(row["region"] for rows in coverage.values() for row in rows))
    share = {side: {row["region"]: row["seen_share"] for row in rows} for side, rows in coverage.items()}
    table = "".join(f"<tr><td style='text-align:left'>{html.escape(region)}</td>"
                    + "".join(f"<td>{100 * share[side][region]:.0f} %</td>" if region in share[side] else "<td>–</td>"
                              for side in coverage) + "</tr>" for region in regions)
    advice = "".join(f"<li>{html.escape(line)}</li>" for line in coverage_advice(coverage))
    pictures = "".join(f"<figure><img src='coverage_{side}.png' width='420'><figcaption>{side} ear: distance to the "
                       "scan (seen under 2 mm)</figcaption></figure>" for side in coverage)
    return (f"<h2>What the scans saw</h2><p>The share of each region of the fitted pinna with a scan point within "
            f"{SEEN_MM:g} mm: where the scan saw nothing, the PPM's template shape stands (and the personal-detail "
            f"layer keeps it).</p><ul>{advice}</ul><table><tr><th>region</th>"
            + "".join(f"<th>{side}</th>" for side in coverage) + f"</tr>{table}</table>{pictures}")


def write_listener_report(name: str, base: str | os.PathLike, localisation: dict, planes_png: str | os.PathLike,
                          out_html: str | os.PathLike, personal_detail: bool = False,
                          coverage: dict[str, list[dict]] | None = None) -> None:
    """The listener's HTML page (beside ``base``'s results, linked relatively); ``personal_detail``: the fits carry
    the personal-detail layer (``base/detail/<side>``), whose scan -> pinna distances the page gives; ``coverage``:
    per ear the :func:`reporting.coverage.pinna_coverage` rows, shown with their advice and pictures
    (``coverage_<side>.png`` beside the page)."""
    base, out_html = Path(base), Path(out_html)
    frame = json.loads((base / "prepared" / "frame.json").read_text())
    fit_dir = "detail" if personal_detail else "align"
    fits = {side: _fit_distances(base / fit_dir / side / "summary.json") for side in ("left", "right")}
    remesh = json.loads((base / "remesh" / "validation.json").read_text())

    def rel(path: Path) -> str:
        return html.escape(os.path.relpath(path, out_html.parent))

    def set_row(set_name: str, row: dict) -> str:
        gains = ("<td></td><td></td>" if set_name == "own"
                 else f"<td>{row['gain_qe_pp']:+.1f}</td><td>{row['gain_pe_deg']:+.1f}</td>")
        kind = "personal (the template)" if set_name == "own" else row.get("kind", "other person")
        return (f"<tr><td>{html.escape(set_name)}</td><td style='text-align:left'>{html.escape(kind)}</td>"
                f"<td>{row['directions']}</td><td>{row.get('sensitivity_db', float('nan')):.2f}</td>"
                f"<td>{row['qe_percent']:.1f}</td><td>{row['pe_deg']:.1f}</td>{gains}</tr>")

    # ranked as the evaluation's ranking: the own set first, then by the quadrant errors another set costs
    ranked = sorted(localisation["sets"].items(), key=lambda item: (item[0] != "own", item[1].get("gain_qe_pp", 0.0)))
    rows = "".join(set_row(set_name, row) for set_name, row in ranked)
    fit_rows = "".join(
        f"<tr><td>{side}</td><td>{fit['median_mm']:.2f}</td><td>{fit['p95_mm']:.2f}</td>"
        f"<td><a href='{rel(base / fit_dir / side / 'aligned_pinna.blend')}'>aligned_pinna.blend</a></td></tr>"
        for side, fit in fits.items())
    fitted = "fitted PPM with its personal detail" if personal_detail else "fitted PPM"
    pictures = "".join(f"<figure><img src='{rel(base / fit_dir / side / 'distance_map.png')}' width='420'>"
                       f"<figcaption>{side} ear: scan to {fitted} (mm)</figcaption></figure>" for side in fits)
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>{html.escape(name)}: personal HRTF</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}td,th{{padding:2px 10px;text-align:right}}
figure{{display:inline-block;margin:0 1em 1em 0}}</style></head><body>
<h1>{html.escape(name)}: personal HRTF</h1>
<h2>Head frame</h2>
<p>The scan was in {html.escape(frame['unit'])}{' and already in the project frame' if frame['kept_as_given'] else
f", turned by {frame['rotation_deg']:.1f}°"}. Ear canals at {frame['left_canal_mm']} and {frame['right_canal_mm']} mm,
nose tip at {frame['nose_tip_mm']} mm (x front, y left, z up; origin between the canals).
Repairs: {html.escape('; '.join(frame['repairs']) or 'none')}.</p>
<h2>Both ears fitted by the PPM{' with the personal-detail layer (shape key Personal_detail)' if personal_detail else ''}</h2>
<table><tr><th>ear</th><th>median (mm)</th><th>p95 (mm)</th><th>for touch-up</th></tr>{fit_rows}</table>
{pictures}
{_coverage_html(coverage)}
<p>Remeshed head: {remesh['n_triangles']:,} triangles, pinna edges {remesh['pinna_edge_mm']['median']:.2f} mm (left)
and {remesh.get('right_pinna_edge_mm', {}).get('median', float('nan')):.2f} mm (right), median.</p>
<h2>HRTFs</h2>
<img src="{rel(Path(planes_png))}" width="1000">
<h2>What personalising buys (baumgartner2014)</h2>
<p>The listener's own set is the template; S = {localisation['sensitivity_db']:.2f} dB gives
{localisation['calibration_qe_percent']:g} % quadrant errors heard through itself. Each other set stands for a
non-individual HRTF heard with that template; the gain is its error minus the own set's.</p>
<table><tr><th>set</th><th>what it is</th><th>directions</th><th>S (dB)</th><th>QE (%)</th><th>PE (°)</th>
<th>ΔQE (pp)</th><th>ΔPE (°)</th></tr>{rows}</table>
<p>S is calibrated anew on the directions of each comparison (8 % QE of the own set there): the quadrant error
depends on how densely the grid samples the sagittal planes. The own set's row gives S on
{localisation['sets']['own']['directions']} directions.</p>
</body></html>
"""
    write_text_atomic(out_html, page)
