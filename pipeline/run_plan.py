"""What one workflow run makes, for which subjects, from which files: the Python behind ``rules/common.smk``.

A :class:`RunPlan` is built once per run from the validated config (``config/schema.yaml``, defaults filled in)
and answers the rules' questions by subject and variant: which head a variant solves, which template a subject
is fitted with, which NumCalc step jobs a solve has, what each job asks a cluster for, what the reports read.
The ``.smk`` keeps only the glue (validation, wildcards, input functions that pass ``wildcards`` on).

Paths are relative to the working directory (the project root); meshes are in millimetres.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from pathlib import Path

import yaml

#: Every HRTF variant of a subject: the reference listener, the unchanged head and the solved conditions; and a new
#: listener's personal head, "personal", and in a validation run its head as scanned, "scanned" (its subject is
#: "listeners/<name>").
HRTF_VARIANTS = ("reference", "original", "ppm", "own_pinna", "default_ppm", "ppm_detail", "ppm_hard", "ppm_detail_hard",
                 "nricp_hard", "scan_hard", "personal", "scanned")
#: The control conditions (the own pinna put back; the template placed by the global pose only).
CONTROLS = ("own_pinna", "default_ppm", "ppm_detail", "ppm_hard", "ppm_detail_hard", "nricp_hard", "scan_hard")


class RunConfigError(ValueError):
    """A config that names data which is not there; the message names the key and the fix."""


def apply_demo_overrides(config: dict) -> None:
    """With no dataset (``data_root`` empty), the demo's hrtf keys and remeshing bands replace the general ones
    (in place; validate again afterwards)."""
    config["hrtf"].update(config["demo"]["hrtf"])
    config["stitch"]["bands"] = config["demo"]["bands"]


def subjects_of(config: dict, data_root: Path) -> list[str]:
    """Subjects of a dataset folder: every ``<subject>/pinna_left_crop.ply``, narrowed by config subjects_table."""
    found = sorted(p.name for p in data_root.iterdir() if (p / "pinna_left_crop.ply").is_file())
    if not found:
        raise RunConfigError(
            f"config key data_root={config['data_root']!r}: no <subject>/pinna_left_crop.ply under it; "
            "point data_root to a dataset folder or leave it empty for the demo")
    if not config["subjects_table"]:
        return found
    from ppm.dataset import read_subjects_table  # noqa: PLC0415

    wanted = read_subjects_table(config["subjects_table"])
    unknown = [s for s in wanted if s not in found]
    if unknown:
        raise RunConfigError(
            f"config key subjects_table={config['subjects_table']!r}: subject(s) {', '.join(unknown)} have no "
            f"pinna_left_crop.ply under data_root={config['data_root']!r}; known: {', '.join(found)}")
    return wanted


def check_embedded_backend(config: dict) -> None:
    """An explicit hrtf.embedded_device (opencl, cuda) must have passed its probe on this machine before any job
    starts (:mod:`mesh2hrtf_io.backends`; the verdict is cached, so only the first run of a machine probes)."""
    hrtf = config["hrtf"]
    device = hrtf.get("embedded_device", "auto")
    if hrtf["enabled"] and hrtf["solver"] == "embedded" and device in ("opencl", "cuda"):
        from mesh2hrtf_io.backends import choose_backend  # noqa: PLC0415

        choose_backend(device)  # raises with the probe's failure and the setting to change


def configfile_settings(configfiles: Iterable[str], workdir: Path) -> tuple[list[str], list[str]]:
    """How the evaluation was configured, for its README: the configfiles that lie in ``workdir`` (relative), and
    for each one outside it what it set ("path: key = value, ..."; a clone does not have such a file)."""
    from reporting.evaluation_pages import flat_settings  # noqa: PLC0415

    inside, outside = [], []
    for path in configfiles:
        if Path(path).resolve().is_relative_to(workdir.resolve()):
            inside.append(os.path.relpath(path, workdir))
        else:
            settings = flat_settings(yaml.safe_load(Path(path).read_text()) or {})
            outside.append(f"{path}: " + ", ".join(f"{key} = {value}" for key, value in settings))
    return inside, outside


class RunPlan:
    """The subjects of a run and every path and resource its rules ask for (config validated beforehand)."""

    def __init__(self, config: dict):
        self.config = config
        self.demo = not config["data_root"]
        if self.demo:
            self.data_root = Path("results/demo_data")
            self.subjects = [f"demo{i:02d}" for i in range(1, config["demo"]["subjects"] + 1)]
        else:
            self.data_root = Path(config["data_root"])
            if not self.data_root.is_dir():
                raise RunConfigError(
                    f"config key data_root={config['data_root']!r}: no such folder; give a dataset folder of "
                    "<subject>/pinna_left_crop.ply, or leave data_root empty for the demo")
            self.subjects = subjects_of(config, self.data_root)
        self.evaluation_folder = config["evaluation"]["folder"]
        self._check_frequency_bands()
        from listener.errors import ListenerError  # noqa: PLC0415
        from listener.table import listeners_of  # noqa: PLC0415

        try:
            self.listeners = listeners_of(config)
        except ListenerError as error:
            raise RunConfigError(str(error)) from error

    @property
    def hrtf(self) -> dict:
        return self.config["hrtf"]

    # --- subjects, templates, conditions -------------------------------------------------------------------
    def demo_seed(self, subject: str) -> int:
        """Random seed of a demo subject: config demo.seed for demo01, + 1 for each next one."""
        return self.config["demo"]["seed"] + self.subjects.index(subject)

    def align_template(self, subject: str) -> str:
        """The template a subject is fitted with: built without that subject from the dataset, or, for the demo
        (whose ears are made by the packaged PPM), the packaged template."""
        if self.demo:
            from ppm.template.store import default_template_dir  # noqa: PLC0415

            return str(default_template_dir() / "template_left.ply")
        return f"results/templates/without_{subject}/template_left.ply"

    def evaluation_conditions(self, subject: str) -> list[str]:
        """The solved conditions of a subject's evaluation (config evaluation.conditions); a control only for the
        subjects of evaluation.<control>_subjects (original_subjects, own_pinna_subjects, default_ppm_subjects,
        ppm_detail_subjects; hard_subjects for the *_hard conditions, or scan_hard_subjects where given for
        scan_hard), all when that list is empty; never one that evaluation.not_solved says the pipeline could not
        build for the subject."""
        evaluation = self.config["evaluation"]
        failed = self.not_solved(subject)

        def chosen(condition: str) -> bool:
            key = f"{condition}_subjects"
            if key not in evaluation and condition.endswith("_hard"):
                key = "hard_subjects"
            subjects = evaluation.get(key) or []  # ppm has no such list: always
            return (not subjects or subject in subjects) and condition not in failed

        return [c for c in evaluation["conditions"] if chosen(c)]

    def not_solved(self, subject: str) -> dict[str, str]:
        """The conditions of evaluation.conditions that the pipeline could not build for ``subject``, with the
        reason (config evaluation.not_solved); the subject's list of hard_subjects etc. would otherwise ask for
        them."""
        failed = dict((self.config["evaluation"].get("not_solved") or {}).get(subject) or {})
        return {c: r for c, r in failed.items() if c in self.config["evaluation"]["conditions"]}

    @staticmethod
    def detail_target(subject: str, detailed: str) -> str:
        """The prepared scan a personal-detail layer is drawn towards: the clean crop's (ppm_detail) or the fixed
        defective scan's (ppm_detail_hard)."""
        if detailed == "ppm_detail_hard":
            return f"results/{subject}/controls/hard/target/pinna_target.ply"
        return f"results/{subject}/target/pinna_target.ply"

    def detail_evidence(self, subject: str, detailed: str) -> str:
        """What a personal-detail layer takes its evidence from: the whole scan the fit's target was cut from (the
        clean crop for ppm_detail, the fixed defective scan for ppm_detail_hard), so that the lobule and the skin
        ring the pinna segmentation leaves out count too."""
        if detailed == "ppm_detail_hard":
            return f"results/{subject}/controls/hard/scan.ply"
        return str(self.data_root / subject / "pinna_left_crop.ply")

    @staticmethod
    def control_pinna(subject: str, control: str) -> str:
        """The pinna a control condition stitches onto the head (mm): the head's own pinna region (own_pinna),
        the PPM fit with its personal-detail layer (ppm_detail), the same three from the subject's fixed defective
        scan (ppm_hard, ppm_detail_hard, nricp_hard: the template deformed by free-form NRICP) or the template
        placed by the global pose only (default_ppm); for scan_hard, the defective scan itself made watertight by
        screened Poisson reconstruction, cut under the rim of ppm_hard's pinna (:mod:`stitching.reconstruction`)."""
        if control in ("own_pinna", "scan_hard"):
            return f"results/{subject}/controls/{control}/pinna.ply"
        if control in ("ppm_detail", "ppm_hard", "ppm_detail_hard", "nricp_hard"):
            return f"results/{subject}/controls/{control}/align/aligned_pinna.ply"
        return f"results/{subject}/controls/default_ppm/align/aligned_pinna.ply"

    # --- heads, projects, solves ---------------------------------------------------------------------------
    def frequencies(self):
        """Frequencies (Hz) of the HRTF projects, from config hrtf.frequencies_hz (any form of
        mesh2hrtf_io/data/frequency_sets.yaml)."""
        from mesh2hrtf_io.frequency_sets import frequencies_from_spec  # noqa: PLC0415

        return frequencies_from_spec(self.hrtf["frequencies_hz"])

    def store_of(self, subject: str, variant: str) -> str | None:
        """Where solved steps of a subject's variant are kept (config hrtf.step_store), or None."""
        folder = self.hrtf["step_store"]
        return str(Path(folder) / subject / variant) if folder else None

    def head_mesh_of(self, subject: str, variant: str) -> str:
        """The head mesh (mm) whose HRTFs a subject's variant stands for ("original": the reference head itself,
        solved here as an evaluation condition, so that the solved conditions are also compared with this
        pipeline's own solve of the unchanged head). A head the pipeline builds (BUILT_HEADS) is taken from the
        step store when it keeps one (``head.ply``, saved at the export): its stored steps were solved for exactly
        that mesh, which a rebuild on another machine does not reproduce bit for bit."""
        from mesh2hrtf_io.step_store import stored_head  # noqa: PLC0415
        from reporting.solve_plan import BUILT_HEADS  # noqa: PLC0415

        if variant in ("reference", "original"):
            return str(self.data_root / subject / self.hrtf["reference_head"])
        if variant not in BUILT_HEADS:
            raise RunConfigError(f"unknown HRTF variant {variant!r}; known: {HRTF_VARIANTS}")
        kept = stored_head(self.store_of(subject, variant))
        if kept is not None:
            return str(kept)
        if variant in ("ppm", "personal"):
            return f"results/{subject}/remesh/head.ply"
        if variant == "scanned":
            return f"results/{subject}/scanned/head.ply"
        return f"results/{subject}/controls/{variant}/head.ply"

    def given_reference_sofa(self, subject: str) -> Path:
        """Where the dataset keeps a subject's reference HRIRs (config localisation.reference_sofa; may be
        absent)."""
        return self.data_root / subject / self.config["localisation"]["reference_sofa"]

    def hrtf_export_inputs(self, subject: str, variant: str) -> dict:
        """The head mesh and, with config hrtf.grid = reference_sofa, the reference SOFA whose directions the
        project is solved at (so that solved and reference ears combine direction by direction)."""
        from mesh2hrtf_io.step_store import stored_head  # noqa: PLC0415

        inputs = {"head": self.head_mesh_of(subject, variant)}
        store = self.store_of(subject, variant)
        if variant == "ppm" and store and stored_head(store) is None:
            # a PPM head built now and kept at the export: the landmarks of its fit are kept with it
            # (reporting.kept_fit)
            inputs.update(self.fit_landmark_inputs(subject, prefix="fit"))
        return {**inputs, **self.grid_inputs(subject)}

    def grid_inputs(self, subject: str) -> dict:
        """With config hrtf.grid = reference_sofa, ``{"grid_sofa": the subject's reference SOFA}`` (its directions
        are the project's grid); for a new listener (always the "full" grid) the SOFA of config
        listener.dataset_grid, whose directions are added to it, where given; else nothing."""
        if self.is_listener(subject):
            dataset = (self.config.get("listener") or {}).get("dataset_grid") or ""
            return {"grid_sofa": dataset} if dataset else {}
        if self.hrtf["grid"] != "reference_sofa":
            return {}
        given = self.given_reference_sofa(subject)
        if not given.is_file():
            raise RunConfigError(f"config hrtf.grid=reference_sofa: {given} is missing; give the reference HRIRs "
                                 "or use hrtf.grid: sagittal")
        return {"grid_sofa": str(given)}

    def sources(self) -> list[str]:
        """Source folders of a project: source_1 (left ear) and, for both ears, source_2 (right ear)."""
        return ["1", "2"] if self.hrtf["ears"] == "both" else ["1"]

    def steps_of(self, subject: str, variant: str) -> list[str]:
        """The status files of a subject's variant's solve: every NumCalc step job (hrtf.steps_per_job steps each,
        never across the edge of a frequency band of a banded head), or the subject's embedded job."""
        if self.hrtf["solver"] == "embedded":
            return [f"results/{subject}/hrtf/embedded.json"]
        base = f"results/{subject}/hrtf/{variant}/steps"
        per_job = self.hrtf["steps_per_job"]
        parts = (self.band_steps() + [self.full_mesh_steps()] if self.banded(variant, subject)
                 else [list(range(1, len(self.frequencies()) + 1))])
        ranges = [(part[k], part[min(k + per_job, len(part)) - 1]) for part in parts if part
                  for k in range(0, len(part), per_job)]
        return [f"{base}/source_{s}/steps_{a}-{b}.json" for s in self.sources() for a, b in ranges]

    # --- a mesh per frequency band (NumCalc) -----------------------------------------------------------------
    @property
    def frequency_bands(self) -> list[dict]:
        """hrtf.frequency_bands.bands: [{up_to_hz, edges_mm}, ...] from the lowest band up."""
        return (self.hrtf.get("frequency_bands") or {}).get("bands") or []

    def banded(self, variant: str, subject: str | None = None) -> bool:
        """Whether a variant's head (of ``subject``, where given) is solved on a mesh per frequency band (NumCalc,
        listed in hrtf.frequency_bands.variants, bands given, and the subject's head not kept on its full mesh by
        hrtf.frequency_bands.full_mesh_heads, as heads solved before a variant was banded are)."""
        settings = self.hrtf.get("frequency_bands") or {}
        listed = settings.get("variants") or []
        kept_full = subject is not None and variant in ((settings.get("full_mesh_heads") or {}).get(subject) or [])
        return (self.hrtf["solver"] == "numcalc" and variant in listed and bool(self.frequency_bands)
                and not kept_full)

    def _check_frequency_bands(self) -> None:
        if not any(self.banded(v) for v in HRTF_VARIANTS):
            return
        limits = [band["up_to_hz"] for band in self.frequency_bands]
        if any(b <= a for a, b in zip(limits, limits[1:])):
            raise RunConfigError(f"config hrtf.frequency_bands.bands: up_to_hz must increase from band to band, got "
                                 f"{limits}")
        distances = len(self.config["stitch"]["bands"])
        for band in self.frequency_bands:
            if len(band["edges_mm"]) != distances:
                raise RunConfigError(
                    f"config hrtf.frequency_bands.bands (up to {band['up_to_hz']:g} Hz): {len(band['edges_mm'])} edge "
                    f"lengths for the {distances} distance bands of stitch.bands; give one edge length per distance band")

    def band_steps(self) -> list[list[int]]:
        """The 1-based steps of the frequency set in each frequency band (above the band below, up to its
        up_to_hz)."""
        frequencies = self.frequencies()
        lower, out = 0.0, []
        for band in self.frequency_bands:
            out.append([i + 1 for i, f in enumerate(frequencies) if lower < f <= band["up_to_hz"]])
            lower = band["up_to_hz"]
        return out

    def full_mesh_steps(self) -> list[int]:
        """The steps above the highest frequency band: solved on the full mesh."""
        top = self.frequency_bands[-1]["up_to_hz"] if self.frequency_bands else 0.0
        return [i + 1 for i, f in enumerate(self.frequencies()) if f > top]

    def band_of_step(self, subject: str, variant: str, step: int) -> int | None:
        """The frequency band (1-based) whose mesh solves a step of a subject's variant, None for the full mesh."""
        if not self.banded(variant, subject):
            return None
        for band, steps in enumerate(self.band_steps(), start=1):
            if step in steps:
                return band
        return None

    @staticmethod
    def project_of(subject: str, variant: str, band: int | None = None) -> str:
        """The Mesh2HRTF project of a variant's full mesh, or of its band mesh ``band`` (1-based)."""
        base = f"results/{subject}/hrtf/{variant}"
        return f"{base}/project" if band is None else f"{base}/band_{band}/project"

    def band_store_of(self, subject: str, variant: str, band: int | None) -> str | None:
        """The step store folder of a variant's full mesh, or of its band mesh ``band``."""
        store = self.store_of(subject, variant)
        return store if store is None or band is None else str(Path(store) / f"band_{band}")

    def step_project(self, subject: str, variant: str, first: int) -> str:
        """The project a NumCalc job starting at step ``first`` solves."""
        return self.project_of(subject, variant, self.band_of_step(subject, variant, first))

    def step_store(self, subject: str, variant: str, first: int) -> str | None:
        """The store of the steps of a NumCalc job starting at step ``first``."""
        return self.band_store_of(subject, variant, self.band_of_step(subject, variant, first))

    def band_projects(self, subject: str, variant: str) -> dict[str, list[int]]:
        """Each band project of a banded variant with its steps (empty for a variant on one mesh)."""
        if not self.banded(variant, subject):
            return {}
        return {self.project_of(subject, variant, band): steps
                for band, steps in enumerate(self.band_steps(), start=1) if steps}

    def band_remesh_bands(self, band: int) -> list[dict]:
        """The remeshing bands of band mesh ``band``: stitch.bands' distances with the band's edge lengths."""
        from stitching.frequency_bands import band_mesh_bands  # noqa: PLC0415

        distances = [distance["up_to_mm"] for distance in self.config["stitch"]["bands"]]
        bands = band_mesh_bands(distances, self.frequency_bands[band - 1]["edges_mm"])
        return [{"up_to_mm": distance, "edge_mm": b.edge_mm, "max_deviation_mm": b.max_deviation_mm}
                for distance, b in zip(distances, bands)]

    def band_head_inputs(self, subject: str, variant: str) -> dict:
        """What a band mesh is made from: the variant's full head (mm) and the subject's left pinna crop (the
        distances to the pinna; a new listener's crop from its head)."""
        crop = (f"results/{subject}/prepared/pinna_left_crop.ply" if self.is_listener(subject)
                else str(self.data_root / subject / "pinna_left_crop.ply"))
        return {"head": self.head_mesh_of(subject, variant), "pinna": crop}

    def band_export_inputs(self, subject: str, variant: str, band: int) -> dict:
        """The band mesh and its source faces a band project is exported from: those kept in the band's step store
        (``head.ply``, ``sources.json``) where kept, else made now; and the grid SOFA as for the full project."""
        from mesh2hrtf_io.step_store import stored_head  # noqa: PLC0415

        store = self.band_store_of(subject, variant, band)
        kept = stored_head(store)
        if kept is not None and (kept.parent / "sources.json").is_file():
            inputs = {"head": str(kept), "sources": str(kept.parent / "sources.json")}
        else:
            base = f"results/{subject}/hrtf/{variant}/band_{band}"
            inputs = {"head": f"{base}/head.ply", "sources": f"{base}/sources.json"}
        return {**inputs, **self.grid_inputs(subject)}

    def solved_variants(self, subject: str) -> list[str]:
        """The heads whose HRTFs are solved for a subject: the reference head when the dataset has no reference
        HRIRs (config localisation.reference_sofa), and every evaluation condition (the PPM head first); for a new
        listener its personal head, and its head as scanned with config listener.scanned_head."""
        if self.is_listener(subject):
            return ["personal"] + (["scanned"] if self.listener_scanned_head else [])
        given = self.given_reference_sofa(subject).is_file()
        return ([] if given else ["reference"]) + self.evaluation_conditions(subject)

    # --- cluster resources ---------------------------------------------------------------------------------
    def numcalc_job_costs(self, project: str, first: int, last: int):
        """Predicted costs of steps ``first``..``last`` of one NumCalc job (mesh2hrtf_io.numcalc_cost), or None
        before the export (dry run) or without a NumCalc binary."""
        from mesh2hrtf_io.numcalc import NumCalcError, find_numcalc  # noqa: PLC0415
        from mesh2hrtf_io.numcalc_cost import project_step_costs  # noqa: PLC0415

        if not (Path(project) / "parameters.json").is_file():
            return None
        try:
            costs = project_step_costs(project, find_numcalc(self.hrtf["numcalc"] or None))
        except (NumCalcError, ValueError, OSError):
            return None
        return costs[first - 1:last]

    def numcalc_step_mem_mb(self, project: str, first: int, last: int, attempt: int) -> int:
        """Memory of a NumCalc job (its largest step) from `NumCalc -estimate_ram`, +20 %, +50 % per retry."""
        costs = self.numcalc_job_costs(project, first, last)
        gigabytes = max(c.memory_gb for c in costs) if costs else 2.0
        return int(1024 * max(gigabytes, 0.25) * 1.2 * (1 + 0.5 * (attempt - 1)))

    def numcalc_step_runtime_min(self, project: str, first: int, last: int, attempt: int) -> int:
        """Wall-clock limit of a NumCalc job (minutes): its predicted steps x 3 (+50 % per retry), at least 10;
        config hrtf.step_runtime_min per step when no prediction can be made. x 3, not x 2: the steps below
        ~1 kHz, where NumCalc's memory estimate jumps (12.7 GB against 2.6 GB on P067's own_pinna head), took up to
        1.9 x their prediction here (1148 and 1041 s against 646 s; mid-band steps 0.7-1.7 x)."""
        costs = self.numcalc_job_costs(project, first, last)
        if not costs:
            return int(self.hrtf["step_runtime_min"] * (last - first + 1))
        return max(10, int(round(3 * sum(c.seconds for c in costs) / 60 * (1 + 0.5 * (attempt - 1)))))

    def embedded_on_gpu(self) -> bool:
        """Whether the embedded solver is asked to run on a GPU (hrtf.embedded_device: cuda)."""
        return self.hrtf.get("embedded_device", "auto") == "cuda"

    def embedded_costs(self, projects: Iterable[str]) -> list | None:
        """(dense cost model estimate, number of frequencies) of each exported project, or None before the export
        (dry run)."""
        from mesh2hrtf_io.bem import estimate_cost  # noqa: PLC0415
        from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415

        backend = "cuda" if self.embedded_on_gpu() else "numba"
        costs = []
        for project in projects:
            if not (Path(project) / "parameters.json").is_file():
                return None
            solved = read_project(project)
            costs.append((estimate_cost(len(solved.vertices_m), len(solved.faces), len(solved.evaluation_points_m),
                                        backend=backend), len(solved.frequencies_hz)))
        return costs

    def embedded_runtime_min(self, projects: Iterable[str], attempt: int) -> int:
        """Wall-clock request (minutes) of a subject's embedded-solver job from the dense cost model: 3 x the
        predicted seconds of every frequency of every head + 5 min of numba compilation (at least 10 min); +50 %
        per retry. Before the export (dry run): config hrtf.step_runtime_min per frequency."""
        costs = self.embedded_costs(projects)
        if costs is None:
            return int(self.hrtf["step_runtime_min"] * len(self.frequencies()))
        seconds = 300.0 + sum(3.0 * cost.seconds_per_frequency * n for cost, n in costs)
        return max(10, int(round(seconds / 60.0 * (1 + 0.5 * (attempt - 1)))))

    def embedded_mem_mb(self, projects: Iterable[str]) -> int:
        """Memory of the embedded solver (its largest head, one at a time) from its dense-operator model; on a GPU
        the dense system lives in the GPU's memory (checked there before the first frequency) and the host needs
        little."""
        if self.embedded_on_gpu():
            return 8192
        costs = self.embedded_costs(projects)
        if costs is None:
            return 4096
        return int(1024 * max(cost.memory_gb_per_frequency for cost, _ in costs) * 1.3) + 1500

    # --- localisation and reports --------------------------------------------------------------------------
    def reference_sofa(self, subject: str) -> str:
        """The reference listener's HRIRs: the dataset's own SOFA file when present, else computed."""
        given = self.given_reference_sofa(subject)
        if given.is_file():
            return str(given)
        return f"results/{subject}/hrtf/reference/HRIR.sofa"

    def reference_frequencies(self, subject: str) -> list[float] | None:
        """The sparse set the PPM head was solved at, when the reference is the dataset's own (full) HRIR file:
        the localisation rule samples and rebuilds the reference there, like with like. None otherwise."""
        from mesh2hrtf_io.frequency_sets import is_linear_grid  # noqa: PLC0415

        frequencies = self.frequencies()
        if is_linear_grid(frequencies) or not self.reference_sofa(subject).startswith(str(self.data_root)):
            return None
        return frequencies.tolist()

    def localisation_inputs(self, subject: str) -> dict:
        """The reference HRIRs and the HRIRs of every solved condition of the subject (by condition name)."""
        inputs = {"reference": self.reference_sofa(subject)}
        for condition in self.evaluation_conditions(subject):
            inputs[condition] = f"results/{subject}/hrtf/{condition}/HRIR.sofa"
        return inputs

    def fit_landmark_inputs(self, subject: str, prefix: str | None = None) -> dict:
        """The landmarks on a subject's aligned PPM that label its scan points by region: the kept fit's
        (``fit_landmarks.json`` beside the kept PPM head, :mod:`reporting.kept_fit`), else the alignment and the
        template's landmarks.yaml. Keys start with ``prefix`` (default: the subject)."""
        from reporting.kept_fit import fit_landmarks_path, kept_fit_landmarks  # noqa: PLC0415

        prefix = subject if prefix is None else prefix
        store = self.store_of(subject, "ppm")
        if kept_fit_landmarks(store) is not None:
            return {f"{prefix}_fit_landmarks": str(fit_landmarks_path(store))}
        return {f"{prefix}_aligned": f"results/{subject}/align/aligned_pinna.ply",
                f"{prefix}_landmarks": str(Path(self.align_template(subject)).parent / "landmarks.yaml")}

    def evaluation_report_inputs(self) -> dict:
        """Everything the dataset evaluation reads: per subject the localisation, the target scan and, per
        condition, the distances, the collected HRTFs and the solve statuses (for the CPU time)."""
        inputs = {}
        for subject in self.subjects:
            inputs[f"{subject}_localisation"] = f"results/{subject}/localisation/qe_pe.json"
            inputs[f"{subject}_reference"] = self.reference_sofa(subject)  # the paper's protocol completes ears with it
            inputs[f"{subject}_target"] = f"results/{subject}/target/pinna_target.ply"
            # the regions of the scan (where the geometry differs): the template's landmarks on the aligned PPM,
            # those of the fit that made the kept PPM head where the store keeps them (then no template or
            # alignment needed)
            inputs.update(self.fit_landmark_inputs(subject))
            if any(c.endswith("_hard") for c in self.evaluation_conditions(subject)):
                inputs[f"{subject}_hard_scan"] = f"results/{subject}/controls/hard/scan.ply"  # kept with the results
            for condition in self.evaluation_conditions(subject):
                inputs[f"{subject}_{condition}_distances"] = f"results/{subject}/evaluation/{condition}/distances.json"
                inputs[f"{subject}_{condition}_hrtf"] = f"results/{subject}/hrtf/{condition}/HRTF.sofa"
                inputs[f"{subject}_{condition}_head"] = self.head_mesh_of(subject, condition)
                inputs[f"{subject}_{condition}_steps"] = self.steps_of(subject, condition)
        # the measured non-individual sets judged beside the conditions (reporting.nonindividual)
        for entry in self.config["evaluation"].get("nonindividual") or []:
            inputs[f"nonindividual_{entry['name']}"] = entry["file"]
        return inputs

    def subject_report_inputs(self, subject: str) -> dict:
        """Every per-subject result the report shows (the localisation only when HRTFs are computed)."""
        base = f"results/{subject}"
        inputs = {"align": f"{base}/align/summary.json", "remesh": f"{base}/remesh/validation.json"}
        if self.hrtf["enabled"]:
            inputs["localisation"] = f"{base}/localisation/qe_pe.json"
        if self.demo:  # the demo's fidelity note and the parameters its ear was made with
            inputs["demo"] = str(self.data_root / subject / "demo.json")
            inputs["truth"] = str(self.data_root / subject / "truth_parameters.json")
        return inputs

    def dataset_report_inputs(self) -> dict:
        """Every subject report (and, in the demo, one subject's fidelity note)."""
        inputs: dict = {"subjects": [f"results/{subject}/report.html" for subject in self.subjects]}
        if self.demo:
            inputs["demo"] = str(self.data_root / self.subjects[0] / "demo.json")
        return inputs

    # --- new listeners ---------------------------------------------------------------------------------------
    def listener_head(self, listener: str) -> str:
        """The head scan of a listener (config listeners)."""
        return str(self.listeners[listener].head)

    def listener_ear_scan(self, listener: str, side: str) -> str:
        """The separate scan of a listener's ear on ``side`` (config listeners: left_ear, right_ear)."""
        return str(self.listeners[listener].ear_scans[side])

    def listener_ear_scan_frame(self, listener: str) -> str:
        """How a listener's separate ear scans reach its head (config listeners: ear_scan_frame): 'any' (registered
        onto the head's ears) or 'head' (placed by the head's frame: the scans share the head scan's coordinates)."""
        return self.listeners[listener].ear_scan_frame

    def listener_target_scan(self, listener: str, side: str) -> str:
        """What a listener's ear is fitted to: its separate scan registered onto the head where one is given, else
        the ear cut from the head."""
        base = f"results/listeners/{listener}/prepared"
        return (f"{base}/ear_scan_{side}.ply" if side in self.listeners[listener].ear_scans
                else f"{base}/pinna_{side}_crop.ply")

    @property
    def listener_personal_detail(self) -> bool:
        """Whether a listener's fits get their personal-detail layer before the stitch (config
        ``listener.personal_detail``)."""
        return bool((self.config.get("listener") or {}).get("personal_detail", True))

    @property
    def listener_detail_settings(self) -> dict:
        """Settings of the personal-detail layer that a listener's fits are laid with instead of the packaged ones
        (config ``listener.personal_detail_settings``, names of ppm/data/personal_detail.yaml); checked here, so that a
        misspelt name stops the run before any job starts."""
        from ppm.align.detail import DetailSettings  # noqa: PLC0415
        from ppm.errors import PpmError  # noqa: PLC0415

        settings = dict((self.config.get("listener") or {}).get("personal_detail_settings") or {})
        try:
            DetailSettings.packaged(**settings)
        except (PpmError, TypeError, ValueError) as error:
            raise RunConfigError(f"config listener.personal_detail_settings: {error}; use the names and values of "
                             "ppm/data/personal_detail.yaml, or leave it empty for the packaged layer") from error
        return settings

    @property
    def listener_scanned_head(self) -> bool:
        """Whether a listener's head as scanned is solved too (config ``listener.scanned_head``): the paper
        protocol's reference in a validation run."""
        return bool((self.config.get("listener") or {}).get("scanned_head"))

    def listener_pinna(self, listener: str, side: str) -> str:
        """The pinna stitched onto a listener's head on ``side`` (left-ear frame, mm): the PPM fit, with its
        personal-detail layer when :attr:`listener_personal_detail` is on."""
        step = "detail" if self.listener_personal_detail else "align"
        return f"results/listeners/{listener}/{step}/{side}/aligned_pinna.ply"

    def listener_template(self) -> str:
        """The template pinna both ears of every listener are fitted with."""
        from listener.errors import ListenerError  # noqa: PLC0415
        from listener.table import listener_template  # noqa: PLC0415

        try:
            return listener_template(self.config)
        except ListenerError as error:
            raise RunConfigError(str(error)) from error

    @property
    def listener_subjects(self) -> list[str]:
        """The subjects the HRTF rules know new listeners by: ``listeners/<name>``."""
        return [f"listeners/{name}" for name in self.listeners]

    @staticmethod
    def is_listener(subject: str) -> bool:
        return subject.startswith("listeners/")

    @property
    def solved_subjects(self) -> list[str]:
        """The subjects whose heads this run solves: the new listeners when there are any, else the subjects."""
        return self.listener_subjects if self.listeners else self.subjects

    def export_settings(self, subject: str) -> dict:
        """config hrtf for a subject's export; a new listener's grid is always "full" (sagittal planes all round
        the head: a personal HRTF set, not only the planes the localisation model reads)."""
        return {**self.hrtf, "grid": "full"} if self.is_listener(subject) else self.hrtf

    def listener_comparison_sets(self, listener: str) -> dict[str, dict]:
        """The sets a listener's own is compared with in its report, by name: the run's other listeners' HRTFs and
        config listener.comparison_sets (a SOFA path, named by its folder, or file name where folders repeat; or a
        measured set {name, file, kind, sampling_rate_hz}), each as {file, kind[, sampling_rate_hz]}."""
        sets = {name: {"file": f"results/listeners/{name}/hrtf/personal/HRTF.sofa", "kind": "listener of this run"}
                for name in self.listeners if name != listener}
        for entry in (self.config.get("listener") or {}).get("comparison_sets") or []:
            if isinstance(entry, dict):
                sets[entry["name"]] = {key: entry[key] for key in ("file", "kind", "sampling_rate_hz") if key in entry}
                continue
            name = Path(entry).parent.name or Path(entry).stem
            sets[name if name not in sets else Path(entry).stem] = {"file": str(entry), "kind": "other person"}
        missing = [s["file"] for s in sets.values() if not s["file"].startswith("results/") and not Path(s["file"]).is_file()]
        if missing:
            raise RunConfigError(f"config listener.comparison_sets: {missing} not found; give SOFA files of other "
                                 "people's HRTFs (or measured sets with name, file and kind), or none")
        return sets

    def listener_comparisons(self, listener: str) -> dict[str, str]:
        """The files of :meth:`listener_comparison_sets`, by name."""
        return {name: entry["file"] for name, entry in self.listener_comparison_sets(listener).items()}

    def listener_outputs(self) -> list[str]:
        """What a run with listeners makes for each: the frame found, both fits, the remeshed head with both PPM
        pinnae, its both-ear HRIRs and its report."""
        parts = ["prepared/frame.json", "align/left/summary.json", "align/right/summary.json", "coverage.json",
                 "remesh/validation.json", "hrtf/personal/HRIR.sofa", "report.html"]
        if self.listener_scanned_head:
            parts.append("hrtf/scanned/HRIR.sofa")
        return [f"results/listeners/{name}/{part}" for name in self.listeners for part in parts]

    def final_output(self) -> list[str]:
        """Everything `snakemake --cores 2` makes: with config listeners, only theirs (listener_outputs);
        otherwise PPM pictures; per subject (demo or dataset) the alignment, the head with the PPM pinna stitched
        in and remeshed, and the report; with hrtf.enabled (always in the demo) the HRTFs of the reference and PPM
        heads and their localisation comparison; the dataset report."""
        if self.listeners:
            return self.listener_outputs()
        out = ["results/ppm/default_ppm.png", "results/ppm/range_sheet.png", "results/ppm/default_ppm.blend",
               "results/ppm/default_parameters.csv"]
        out += [f"results/{s}/align/summary.json" for s in self.subjects]
        out += [f"results/{s}/remesh/validation.json" for s in self.subjects]
        if self.hrtf["enabled"]:
            out += [f"results/{s}/localisation/qe_pe.json" for s in self.subjects]
        out += [f"results/{s}/report.html" for s in self.subjects] + ["results/dataset_report.html"]
        if self.evaluation_folder and self.hrtf["enabled"]:
            out.append(f"{self.evaluation_folder}/summary.csv")
        return out

    def solve_plan_text(self, cores: int | Callable[[], int]) -> str | None:
        """The solve plan of this run (reporting/solve_plan.py): NumCalc's steps to solve and restore, or the
        embedded solver's heads with their predicted time on the configured backend; None when nothing is
        solved. ``cores`` may be a function, asked only for NumCalc's plan (Snakemake's ``workflow.cores`` raises in
        a cluster run without --cores)."""
        if not self.hrtf["enabled"]:
            return None
        if self.hrtf["solver"] == "embedded":
            from reporting.solve_plan import embedded_plan_text  # noqa: PLC0415

            heads = [(subject, variant, self.head_mesh_of(subject, variant))
                     for subject in self.solved_subjects for variant in self.solved_variants(subject)]
            return embedded_plan_text(heads, self.hrtf.get("embedded_device", "auto"), len(self.frequencies()))
        from reporting.solve_plan import plan_rows, plan_text  # noqa: PLC0415

        heads, projects, steps = [], {}, {}
        for subject in self.solved_subjects:
            for variant in self.solved_variants(subject):
                heads.append((subject, variant))
                projects[(subject, variant)] = self.project_of(subject, variant)
                if self.banded(variant, subject):
                    steps[(subject, variant)] = self.full_mesh_steps()
                    for band, band_steps in enumerate(self.band_steps(), start=1):
                        part = (subject, f"{variant}/band_{band}")
                        heads.append(part)
                        projects[part], steps[part] = self.project_of(subject, variant, band), band_steps
        rows = plan_rows(self.hrtf["step_store"] or None, heads, len(self.frequencies()),
                         [int(s) for s in self.sources()], projects, steps)
        return plan_text(rows, (cores() if callable(cores) else cores) or 1)
