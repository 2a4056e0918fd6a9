"""`catadioptric simulate`: `simulate(setup)` renders a setup; `write_simulation` writes its four files.

Outputs of `simulate SETUP.toml -o OUT.png`: OUT.png (sRGB, or as `[camera] response` stores light), OUT.toml
(the setup as rendered), OUT.truth.json (per cube, the keys of the reconstruct result) and OUT.gt.npz (per-pixel ground
truth: object_id, via_mirror, ray_distance, mirror_point, reflected_dir).
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from catadioptric.errors import CatadioptricError
from catadioptric.npzfile import MAX_BYTES, NpzWriter
from catadioptric.outputs import OutputSet
from catadioptric.setup import Setup, setup_to_toml

__all__ = ["Simulation", "simulate", "write_simulation", "simulate_to_files", "output_paths"]


@dataclass(frozen=True)
class Simulation:
    setup: Setup
    render: object  # raytrace.render.Render
    truth: dict


def simulate(setup: Setup, spp: int = 4, seed: int = 0, progress=None, workers: int = 2,
             out: dict | None = None) -> Simulation:
    """Render a setup and compute its exact ground truth (no files).

    `out`: optional arrays to render into (`raytrace.render.render`'s `out`).
    """
    from raytrace.render import render
    from raytrace.truth import cube_truth
    camera = setup.camera.build()
    scene = setup.build_scene()
    result = render(scene, camera, spp=spp, seed=seed, progress=progress, workers=workers, out=out)
    cubes = [cube_truth(camera, scene.mirror, cube) for cube in scene.objects]
    truth = {"setup": None, "image": None, "cubes": cubes}
    return Simulation(setup=setup, render=result, truth=truth)


def output_paths(out_png) -> dict:
    """The four output paths of an OUT.png argument."""
    out = Path(out_png)
    if out.suffix.lower() != ".png":
        raise CatadioptricError(f"{out}: -o: expected an output file name ending in .png")
    stem = out.with_suffix("")
    return {"png": out, "toml": stem.with_suffix(".toml"), "truth": Path(f"{stem}.truth.json"),
            "gt": Path(f"{stem}.gt.npz")}


def encode_png(rgb8: np.ndarray) -> bytes:
    """(H, W, 3) uint8 RGB → PNG bytes (Pillow, zlib level 3: importing OpenCV for this alone would
    cost `simulate` 0.13 s of start-up)."""
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb8, dtype=np.uint8), "RGB").save(buf, "PNG", compress_level=3)
    return buf.getvalue()


GT_KEYS = ("object_id", "via_mirror", "ray_distance", "mirror_point", "reflected_dir")
"""The arrays of OUT.gt.npz, in the contract's order."""
MAPPED_KEYS = ("mirror_point", "reflected_dir", "ray_distance")
"""The OUT.gt.npz arrays `simulate_to_files` renders straight into the file (float, stored)."""


def _gt_arrays(r) -> dict:
    h, w = r.object_id.shape
    return dict(object_id=r.object_id.astype(np.int32, copy=False), via_mirror=r.via_mirror.astype(bool, copy=False),
                ray_distance=r.ray_distance.astype(np.float32, copy=False),
                mirror_point=r.mirror_point.reshape(h, w, 3).astype(np.float64, copy=False),
                reflected_dir=r.reflected_dir.reshape(h, w, 3).astype(np.float64, copy=False))


def _png(sim: Simulation) -> bytes:
    """OUT.png's bytes: the render stored as the setup's camera stores light (`[camera] response`; sRGB), demosaiced
    from an RGGB mosaic of it where the camera's images are (`[camera] demosaiced`: OpenCV's VNG), or the raw Bayer
    frame of it where they are such frames (`[camera] mosaic`)."""
    from raytrace.render import linear_to_srgb8
    if sim.setup.camera.mosaic is not None:
        return _raw_frame_png(sim.render.image, sim.setup.camera)
    response = sim.setup.camera.response
    codes = linear_to_srgb8(sim.render.image) if response is None else response.encode8(sim.render.image)
    if sim.setup.camera.demosaiced:
        from raytrace.chroma import demosaiced
        codes = demosaiced(codes)
    return encode_png(codes)


def _raw_frame_png(light, camera) -> bytes:
    """A 16-bit one-channel PNG's bytes: the raw Bayer frame (filter tile `camera.mosaic`) a sensor records of the
    render's linear light, each pixel its filter's channel divided by its white balance gain, from the camera's black
    level (no light) to its white level (full scale; 65535 by default), rounded."""
    from raytrace.chroma import bayer_channels, bayer_mosaic
    sample = bayer_mosaic(np.asarray(light), camera.mosaic)
    if camera.white_balance is not None:
        sample = sample / np.asarray(camera.white_balance)[bayer_channels(camera.mosaic, sample.shape)]
    white = 65535.0 if camera.white_level is None else camera.white_level
    frame = np.round(camera.black_level + np.clip(sample, 0.0, 1.0) * (white - camera.black_level)).astype(np.uint16)
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(frame).save(buf, "PNG", compress_level=3)  # (mode I;16: 16-bit grey)
    return buf.getvalue()


def _write_rest(out: OutputSet, sim: Simulation, paths: dict, png: bytes | None = None) -> None:
    """OUT.png (encoded here unless given), OUT.toml and OUT.truth.json, staged in `out`."""
    truth = dict(sim.truth, image=paths["png"].name, setup=paths["toml"].name)
    out.write_bytes(paths["png"], _png(sim) if png is None else png)
    out.write_text(paths["toml"], setup_to_toml(sim.setup))
    out.write_text(paths["truth"], json.dumps(truth, indent=2) + "\n")


def write_simulation(sim: Simulation, out_png) -> list[Path]:
    """Write OUT.png, OUT.toml, OUT.truth.json and OUT.gt.npz together (all or nothing).

    Floating-point arrays are stored in the .npz as they are (their mantissas are noise: deflating
    a 1600×1200 ray map takes 1.4 s for a 2.5× smaller file); ids and masks are deflated.
    """
    paths = output_paths(out_png)
    with OutputSet() as out:
        _write_rest(out, sim, paths)
        with out.writing(paths["gt"]) as gt_path, NpzWriter(gt_path) as npz:
            for name, arr in _gt_arrays(sim.render).items():
                npz.add(name, arr)
    return list(paths.values())


def simulate_to_files(setup: Setup, out_png, spp: int = 4, seed: int = 0, progress=None,
                      workers: int = 2) -> tuple[Simulation, list[Path]]:
    """`simulate` and `write_simulation` in one pass (what `catadioptric simulate` runs).

    The float ray maps are rendered straight into OUT.gt.npz's pages (`NpzWriter`'s mapped
    members) instead of being rendered to memory and copied into the file: the same PNG, TOML and
    truth bytes and the same arrays in the .npz (laid out for mapping, so not the same .npz bytes as
    `write_simulation`), with about 100 MB less memory to fill at 1600×1200. All or nothing, as
    `write_simulation`. Returns the simulation (its ray maps are views of the written file) and
    the four paths.
    """
    from raytrace.render import OUTPUTS
    paths = output_paths(out_png)
    w, h = setup.camera.resolution
    shapes = {name: ((h, w) + OUTPUTS[name][0], OUTPUTS[name][1]) for name in MAPPED_KEYS}
    if sum(int(np.prod(s)) * np.dtype(t).itemsize for s, t in shapes.values()) > MAX_BYTES // 2:
        sim = simulate(setup, spp=spp, seed=seed, progress=progress, workers=workers)
        return sim, write_simulation(sim, out_png)
    from concurrent.futures import ThreadPoolExecutor
    with OutputSet() as out, ThreadPoolExecutor(1) as thread:
        with out.writing(paths["gt"]) as gt_path, NpzWriter(gt_path, mapped=shapes) as npz:
            sim = simulate(setup, spp=spp, seed=seed, progress=progress, workers=workers, out=npz.arrays)
            png = thread.submit(_png, sim)  # zlib and numpy release the GIL: encode beside the npz
            gt = _gt_arrays(sim.render)
            for name in GT_KEYS:
                if name not in MAPPED_KEYS:
                    npz.add(name, gt[name])
            npz.close(order=GT_KEYS)
        _write_rest(out, sim, paths, png=png.result())
    return sim, list(paths.values())
