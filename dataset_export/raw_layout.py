"""Raw-frame exports (``lsmi``: TIFF raws, ``dng``: Bayer DNG raws) in LSMI's layout (:mod:`dataset_export.lsmi`).

Per camera × place: compose the capture set (:mod:`dataset_export.frames`), find the chart once per view
(:mod:`dataset_export.chart`), write ``<place>_<lights>.<tiff|dng>`` and the mixture ``.npy`` files
atomically and journal the place's ``meta.json`` entry with them; then, per camera, ``meta.json``,
``split.json``, ``illuminants.json`` and the template ``<camera>.dng``.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from illumix.dataset_export import lsmi
from illumix.dataset_export.card import LICENCES, sensor_licence
from illumix.dataset_export.chart import find_chart, scale_corners
from illumix.dataset_export.errors import ExportError
from illumix.dataset_export.frames import Capture, Composer


def _cct(spd: np.ndarray, grid) -> dict[str, float | None]:
    """``{"cct_K": CCT (K, Ohno 2013) or None, "duv": Duv}`` of an SPD, from its CIE 1931 XYZ."""
    import colour

    from illumix.retarget.sensors import get_sensor

    xyz = spd @ get_sensor("XYZ", grid).weights()
    if xyz.sum() <= 0:
        return {"cct_K": None, "duv": 0.0}
    cct, duv = colour.uv_to_CCT(colour.xy_to_UCS_uv(xyz[:2] / xyz.sum()), method="Ohno 2013")
    return {"cct_K": round(float(cct), 1), "duv": round(float(duv), 5)}


def _levels(noise: str | None):
    """The sensor model of the raw frames; its black and white levels must be whole digital numbers
    (a TIFF's DN and a DNG's ``BlackLevel``/``WhiteLevel``; :func:`imagefiles.dng.dng_levels`)."""
    from illumix.engine.spec import CAMERA_NOISE, parse_noise
    from illumix.imagefiles.dng import dng_levels
    from illumix.retarget.errors import SpectralError
    from illumix.retarget.sensor_model import NoiseModel

    if noise and noise.strip().lower() == CAMERA_NOISE:  # parse_noise leaves it to the plan: it would be ignored here
        raise ExportError("--noise camera is /sample's (one estimated sensor's own model); an export states one set of "
                          "levels for every camera: give --noise low|phone|high or key:value pairs")
    model = (parse_noise(noise) if noise else None) or NoiseModel()
    try:
        dng_levels(model)
    except SpectralError:
        raise ExportError(f"--noise gives black level {model.black_level:g} and white level {model.white:g}; the "
                          "raw files state whole digital numbers: give --noise "
                          "'black_level:<integer>;white_level:<integer>'") from None
    return model


def check_frames(st, places, o, fmt) -> None:
    """Refusals of the raw-frame options before anything is written: levels that are not whole
    digital numbers (:func:`_levels`); a DNG frame smaller than libraw reads
    (:data:`imagefiles.dng.DNG_MIN_SIDE`)."""
    _levels(o.noise)
    if fmt.name == "dng":
        _check_dng_sizes(st, places, o.size)


def _check_dng_sizes(st, places, size: tuple[int, int] | None) -> None:
    from illumix.imagefiles.dng import DNG_MIN_SIDE

    for place in places:
        if size is None:
            meta = st.view_meta(place.scene, place.view)
            w, h = meta.width, meta.height
        else:
            w, h = size
        if min(w, h) < DNG_MIN_SIDE:
            raise ExportError(f"--format dng needs frames of at least {DNG_MIN_SIDE}x{DNG_MIN_SIDE} pixels (libraw "
                              f"refuses smaller DNGs); {place.scene}/{place.view} would be {w}x{h}: give a larger "
                              "--size, or --format lsmi")


def _corners(st, place, size: tuple[int, int] | None, cache: dict) -> np.ndarray | None:
    key = (place.scene, place.view)
    if key not in cache:
        vm = st.view_meta(place.scene, place.view)
        name = next((n for n in ("albedo_bands", "albedo") if n in vm.aovs), None)
        c = find_chart(st.read_aov(place.scene, place.view, name)) if name else None
        full = (vm.width, vm.height)
        cache[key] = None if c is None else scale_corners(c, full, size or full)
    return cache[key]


def export_frames(st, places, journal, o, fmt, summary: dict, by_split: dict, on_progress) -> None:
    """Write every camera's LSMI folder (module docstring); fills ``summary``."""
    from illumix.imagefiles.dng import color_matrix, noise_profile, template_bytes

    levels = _levels(o.noise)
    bayer = o.bayer if fmt.bayer else None  # dng without a pattern (--bayer none): LinearRaw RGB frames
    composer = Composer(st, gt=o.gt, size=o.size, noise=o.noise, levels=levels, bayer=bayer)
    lib = composer.ctx.library
    first = places[0]
    grid = st.cube_meta(first.scene, first.view, first.groups[0]).spectral_grid
    sensors = {name: lib.sensor(name, grid) for name in o.sensors}  # unknown names: one line with close matches
    names = sorted({n for p in places for n in p.lighting} | {"D65"})
    spds = {n: lib.illuminant(n, grid) for n in names}
    ccts = {n: _cct(spds[n][0], grid) for n in names}
    # a camera file given by path is named as ILLUMIX_SENSOR_PATH names it (its stem), not by its path
    folders = [lsmi.camera_dir(sensors[s][0].name if lib.local_file("sensors", s) else s) for s in o.sensors]
    if len(set(folders)) != len(folders):
        raise ExportError(f"sensors {o.sensors} map to the same folder name; export them separately")
    if on_progress:
        on_progress(len(sensors) * len(places), None)
    tally = {"errors": [], "skipped": set(), "corners": {},
             "counts": {"cameras": len(sensors), "places": 0, "raw frames": 0, "mixture maps": 0,
                        "ground-truth maps": 0}}
    counts = tally["counts"]
    summary |= {"cameras": [], "illuminants": {n: ccts[n] for n in names if n != "D65" or
                                               any("D65" in p.lighting for p in places)}}
    for (sensor_name, (sensor, skey)), cam in zip(sensors.items(), folders):
        ccm, _ = lib.ccm(sensor, skey, *spds["D65"])
        matrix = color_matrix(sensor.weights(), spds["D65"][0], ccm)
        dng_kw = {"black": int(levels.black_level), "white": int(levels.white), "pattern": o.bayer,
                  "matrix": matrix, "model": sensor_name,  # the sensor model's NoiseProfile with --noise
                  "noise": noise_profile(levels) if o.noise else None}
        entries = _export_places(st, places, journal, composer, o, fmt, cam, sensor_name, dng_kw, ccts, tally,
                                 summary, on_progress)
        splits = {name: [p for p in ps if p in entries] for name, ps in by_split.items()}
        journal.write_json(f"{cam}/meta.json", entries)
        journal.write_json(f"{cam}/split.json", splits)
        journal.write_json(f"{cam}/illuminants.json", {
            n: {**ccts[n], "wavelengths_nm": grid.wavelengths.tolist(), "spd": np.round(spds[n][0], 8).tolist()}
            for n in names})
        journal.write_bytes(f"{cam}.dng", template_bytes(**dng_kw))
        summary["cameras"].append({"sensor": sensor_name, "folder": cam, "licence": sensor_licence(sensor.source)})
    if not counts["places"]:
        raise ExportError("nothing exported: " + "; ".join(summary["skipped"][:3]))
    summary["splits"] = {name: sorted({p for p in ps if any(f"{c}/{p}" not in tally["skipped"] for c in folders)})
                         for name, ps in by_split.items()}
    summary |= {"counts": counts, "gt": summary["samples"][0]["gt"], "target": o.gt or "mixture",
                "noise": o.noise, "noise_model": asdict(levels) if o.noise else None, "bayer": bayer,
                "levels": {"black": int(levels.black_level), "white": int(levels.white)},
                "lsmi_error_deg": {"mean": float(np.mean([e["mean"] for e in tally["errors"]])),
                                   "max": float(np.max([e["max"] for e in tally["errors"]]))},
                "layout": LAYOUT[fmt.name], "reading": READING[fmt.name],
                "licences": sorted({c["licence"] for c in summary["cameras"]} | {LICENCES["illuminants"], LICENCES["scenes"]})}


def _export_places(st, places, journal, composer, o, fmt, cam: str, sensor_name: str, dng_kw: dict, ccts: dict,
                   tally: dict, summary: dict, on_progress) -> dict:
    """One camera's places (each resumed from the journal when done): their ``meta.json`` entries;
    a place the engine refuses is skipped with its reason (``tally``: errors, skipped, counts)."""
    from illumix.retarget.errors import SpectralError

    entries = {}
    for place in places:
        key = f"{cam}/{place.name}"
        rec = journal.done(key)
        if rec is None:
            try:
                cap = composer.capture(place, sensor_name)
            except ExportError:
                raise  # the options, not this place: nothing else would export either
            except SpectralError as exc:
                summary["skipped"].append(f"{sensor_name} {place.scene}/{place.view}: {exc}")
                tally["skipped"].add(key)
                if on_progress:
                    on_progress(1, f"{key} skipped")
                continue
            corners = _corners(st, place, o.size, tally["corners"])
            rec = _write_place(journal, cam, cap, fmt, dng_kw)
            rec["entry"] = lsmi.place_entry(cap, corners, cap.frames[-1].meta["ground_truth"]["method"], ccts,
                                            o.gt or "mixture")
            journal.record(key, rec)
        entries[place.name] = rec["entry"]
        tally["errors"].append(rec["entry"]["LSMIModelErrorDeg"])
        summary["samples"] += rec["samples"]
        tally["counts"]["places"] += 1
        tally["counts"]["raw frames"] += len(rec["samples"])
        tally["counts"]["ground-truth maps"] += sum(f.endswith(lsmi.GT_ILLUM_SUFFIX) for f in rec["files"])
        tally["counts"]["mixture maps"] += sum(f.endswith(".npy") and not f.endswith(lsmi.GT_ILLUM_SUFFIX)
                                               for f in rec["files"])
        if on_progress:
            on_progress(1, key)
    return entries


def _write_place(journal, cam: str, cap: Capture, fmt, dng_kw: dict) -> dict:
    from illumix.imagefiles.dng import write_dng

    files, samples = [], []
    for fr in cap.frames:
        stem = f"{cam}/{cap.place.name}/{cap.place.name}_{fr.lights}"
        raw_rel = stem + fmt.raw_ext
        if fmt.name == "dng":
            journal.write(raw_rel, lambda p, fr=fr: write_dng(p, fr.dn, neutral=fr.neutral, **dng_kw))
        else:
            journal.write(raw_rel, lambda p, fr=fr: lsmi.write_tiff(p, fr.dn))
        files.append(raw_rel)
        if fr.mixture is not None:
            journal.write(stem + ".npy", lambda p, fr=fr: lsmi.write_npy(p, fr.mixture))
            files.append(stem + ".npy")
        journal.write(stem + lsmi.GT_ILLUM_SUFFIX, lambda p, fr=fr: lsmi.write_npy(p, fr.gt_illum))
        files.append(stem + lsmi.GT_ILLUM_SUFFIX)
        samples.append({"file": raw_rel, "params": fr.params, "gt": fr.meta["ground_truth"]["method"],
                        "neutral": [round(v, 8) for v in fr.neutral]})
    return {"files": files, "samples": samples}


LAYOUT = {
    "lsmi": "As the LSMI release (Kim et al., ICCV 2021) lays out one camera: `<camera>.dng` (template: black and "
            "white level), `<camera>/meta.json` (per place `Light1..3` camera-RGB white points with G = 1, "
            "`NumOfLights`, `MCCCoord` at 2x pixel coordinates; absent charts at (-2, -2)), `<camera>/split.json`, "
            "`<camera>/<place>/<place>_<lights>.tiff` (16-bit RGB, BGR order on disk, black level added, clipped at "
            "the white level) and `<place>_<lights>.npy` (mixture H×W×n, -1 where no light reaches the pixel). "
            "Beyond LSMI, per frame `<place>_<lights>_gt_illum.npy`: the ground truth itself (H×W×3 float32, the "
            "white point per pixel in camera RGB with G = 1 — physical: bounce light included —, -1 in all three "
            "channels where undefined); LSMI's scripts never read it. "
            "Lights: `_1`, `_12` (two lights), `_1`, `_12`, `_13`, `_123` (three), as LSMI captured them, all at the "
            "exposure of the all-lit frame. Extra: `<camera>/illuminants.json` (names, CCTs, SPDs) and per place "
            "`Illuminants` (with the groups each light lights), `Scene`, `View`, `ExposureGain`, `GroundTruth`, "
            "`MixtureTarget` (what the mixture files hold: `--gt`) in meta.json.",
    "dng": "The LSMI layout with DNG raws (`<place>_<lights>.dng`: 16-bit Bayer CFA, or LinearRaw RGB with "
           "`--bayer none`; BlackLevel/WhiteLevel, ColorMatrix1 fitted to the sensor under D65, AsShotNeutral = "
           "the ground-truth white point) where the LSMI release has TIFFs; mixture `.npy` files are per pixel "
           "of the DNG.",
}
READING = {
    "lsmi": "LSMI's own scripts run unchanged: copy `2_preprocess_data.py` beside the camera folder, set "
            "`CAMERA = \"<camera>\"`, run it, then train its `SVWB_Unet` on the output. By hand: "
            "`img = cv2.cvtColor(cv2.imread(tiff, cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB) - black`; "
            "`illum = np.load('<place>_<lights>_gt_illum.npy')` (the exact ground truth; valid where "
            "`illum[..., 1] > 0`) or LSMI's model `mixture @ [Light1, Light2]`; white-balanced `img / illum`. "
            "`illumix evaluate OUT` scores against the `_gt_illum.npy` files.",
    "dng": "`rawpy.imread(path)`: `raw_image` (CFA `(H, W)`; LinearRaw `(H, W, 4)`, RGB in `[..., :3]`), "
           "`black_level_per_channel`, `white_level`, "
           "`camera_whitebalance` (1 / AsShotNeutral), `postprocess()` for an sRGB preview.",
}
