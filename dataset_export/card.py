"""The dataset card (``README.md`` at the export's root): what the dataset is, how many of what, which
cameras, illuminants, seed and ground truth, how to read it, and the licences of the data it was
made from. Generated from the run's summary, so it cannot disagree with the files."""

from __future__ import annotations

from illumix.dataset_export.lsmi_target import TARGETS

# Where illumix's spectral data come from, and under which terms (see ../shared/data/*/SOURCE.md).
LICENCES = {
    "colour-science": "colour-science (BSD-3-Clause): CIE illuminants and observer, ColorChecker N Ohta and "
                      "CIE 2017 colour-fidelity reflectances, NPL camera sensitivities",
    "rawtoaces": "rawtoaces-data camera sensitivities (Apache-2.0; AMPAS, Weta Digital physLight, NPL)",
    "upload": "curves uploaded to the store by its users: the uploader's terms",
    "illuminants": "CIE standard illuminants, measured lamp SPDs (SDS_LIGHT_SOURCES) and the CIE 1931 observer via "
                   "colour-science (BSD-3-Clause)",
    "scenes": ("scene materials: CIE 2017 colour-fidelity samples and ColorChecker N Ohta via colour-science "
               "(BSD-3-Clause); ISETCam reflectances (MIT) where a scene names them"),
}


def sensor_licence(source: str) -> str:
    """The licence line of a sensor by its ``source`` (a file path, ``uploaded``, or colour-science's)."""
    s = source.lower()
    if "rawtoaces" in s:
        return LICENCES["rawtoaces"]
    if s in ("uploaded", "user") or s.endswith((".csv", ".json")):
        return LICENCES["upload"]
    return LICENCES["colour-science"]


def _short(name: str) -> str:
    """An illuminant's name in the card: a drawn file by its place in the export (``illuminants/x.csv``)."""
    parts = name.replace("\\", "/").split("/")
    return "/".join(parts[-2:]) if len(parts) > 1 else name


def _sampling_lines(s: dict) -> list[str]:
    if not s.get("sampling"):
        return []
    from illumix.dataset_export.illuminant_draws import ARTIFICIAL_MIX, DAYLIGHT_MIX

    mix = "" if s["sampling"] == "planckian" else (
        f" (artificial: {', '.join(f'{k} {v:.0%}' for k, v in ARTIFICIAL_MIX.items())}; daylight: "
        f"{', '.join(f'{k} {v:.0%}' for k, v in DAYLIGHT_MIX.items())})")
    return [(f"Drawn per place (`--pairs draw:{s['sampling']}`): a daylight and an artificial illuminant{mix}; "
             "drawn SPDs that are no built-in name are in `illuminants/*.csv` (wavelength,value)."), ""]


def _noise_line(s: dict, bayer: str) -> str:
    """The card's sensor-model line: levels, and the noise model (on by default) or that frames are noise-free."""
    head = f"- sensor model: black level {s['levels']['black']}, white level {s['levels']['white']}{bayer}; "
    m = s.get("noise_model")
    if not s.get("noise"):
        return head + "**noise-free** raw frames (`--noise none`: signal quantised, no shot or read noise)"
    detail = (f" — photon shot noise (full well {m['full_well']:g} e-) and read noise ({m['read_noise']:g} e- RMS), "
              f"{m['bit_depth']} bit" if m else "")
    return head + (f"camera noise model `{s['noise']}`{detail}, drawn with each frame's seed (the export's default; "
                   "`--noise none` for noise-free frames); the ground truth is of the noise-free signal")


def _table(rows: list[list[str]], head: list[str]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def dataset_card(s: dict) -> str:
    """Markdown of the card from the export summary ``s`` (:func:`dataset_export.run.export_dataset`)."""
    fmt = s["format"]
    what = "spectral cubes" if fmt == "exr" else "mixed-illuminant raw images with pixel-wise ground truth"
    splits = ", ".join(f"{k} {len(v)} place(s)" for k, v in s["splits"].items())
    out = [f"# illumix export — {fmt} dataset", "",
           (f"Synthetic {what}, exported by `illumix export` from the cube store `{s['store']}` on {s['created']}. "
            "Every raw frame is composed by illumix's sample service code in-process: it holds exactly what "
            "`GET /sample` answers for the parameters `manifest.json` records for it (`samples`)."), "",
           "## Contents", "", _table([[k, v] for k, v in s["counts"].items()], ["what", "how many"]), "",
           f"- seed: `{s['seed']}` (places, lightings, splits and noise are functions of it and the store)",
           f"- splits by scene (no scene in two splits), fractions train/val/test `{s['split']}`: {splits}",
           f"- frame size: {s['size'] or 'as rendered'}", *(f"- note: {w}" for w in s.get("warnings", []))]
    if fmt != "exr":
        kind = ("illumination cubes: bounce light included" if s["gt"] == "physical"
                else "thesis eq. 3.3 mixture of the lights' white points")
        err = s["lsmi_error_deg"]
        bayer = (f", Bayer {s['bayer']}" if s.get("bayer") else
                 ", LinearRaw DNG (RGB per pixel, no mosaic)" if fmt == "dng" else "")
        out += [(f"- ground truth: `{s['gt']}` ({kind}), per frame in `<place>_<lights>_gt_illum.npy` (white point "
                 f"per pixel, camera RGB, G = 1; -1 where undefined)"),
                (f"- what LSMI's trainers read (`--gt {s.get('target', 'mixture')}`): the mixture `.npy` files hold "
                 f"{TARGETS[s.get('target', 'mixture')]}; LSMI's model Σ mixture·Light differs from the ground truth "
                 f"above by {err['mean']:.3f}° mean, {err['max']:.3f}° max"
                 + (" (`--gt physical` fits the mixtures to it)" if s.get("target", "mixture") == "mixture"
                    and s["gt"] == "physical" and err["mean"] >= 0.01 else "")),
                _noise_line(s, bayer), "",
                "## Cameras", "", _table([[c["sensor"], f"`{c['folder']}/`", c["licence"]] for c in s["cameras"]],
                                         ["sensor", "folder", "spectral data"]), "",
                "## Illuminants", "",
                *_sampling_lines(s),
                _table([[_short(n), "" if v["cct_K"] is None else f"{v['cct_K']:.0f} K", f"{v['duv']:+.4f}"]
                        for n, v in s["illuminants"].items()], ["name", "CCT", "Duv"]),
                "", "SPDs (band averages on the store's grid) are in `<camera>/illuminants.json`.", ""]
    out += ["## Layout", "", s["layout"], "", "## Reading it", "", s["reading"], ""]
    if s["skipped"]:
        out += ["## Not exported", "", *(f"- {x}" for x in s["skipped"][:20]),
                *(["- …"] if len(s["skipped"]) > 20 else []), ""]
    out += ["## Licences", "", "The images are generated; what they were generated from:", "",
            *(f"- {line}" for line in s["licences"]), "",
            ("`manifest.json` lists every file with its SHA-256; check them with `sha256sum` or "
             "`python -c \"from illumix.dataset_export.journal import verify_manifest; print(verify_manifest('.'))\"`."), ""]
    return "\n".join(out)
