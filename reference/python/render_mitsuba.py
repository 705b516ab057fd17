"""Renders a scene exported by scatterbench's `reference::mitsuba` with Mitsuba 3.

Usage: python render_mitsuba.py JOB.json

JOB.json (written by the Rust side):
  variant      Mitsuba variant, e.g. "scalar_rgb" or "llvm_ad_rgb"
  spp          samples per pixel of each render
  seeds        one independent render per seed
  scene        a Mitsuba scene dictionary; any {"__transform__": 4x4 rows} value becomes a
               ScalarTransform4f
  output_dir   where to write image_<k>.f32 (float32 little-endian, rows top to bottom,
               channels innermost) and result.json

result.json: version, variant, width, height, channels, load_seconds, render_seconds (wall
time of each render, waiting for it to finish) and render_cpu_seconds (CPU time of the whole
process, all threads, during each render).

The script has no logic of its own beyond this: every modelling decision is made in Rust.
"""

import array
import json
import os
import sys
import time


def convert(value, mi):
    if isinstance(value, dict):
        if set(value) == {"__transform__"}:
            return mi.ScalarTransform4f(value["__transform__"])
        return {k: convert(v, mi) for k, v in value.items()}
    if isinstance(value, list):
        return [convert(v, mi) for v in value]
    return value


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: render_mitsuba.py JOB.json")
    with open(sys.argv[1], encoding="utf-8") as f:
        job = json.load(f)

    import drjit as dr
    import mitsuba as mi

    variant = job["variant"]
    if variant not in mi.variants():
        sys.exit(f"variant {variant!r} is not available (have: {', '.join(mi.variants())})")
    mi.set_variant(variant)

    out = job["output_dir"]
    t0 = time.perf_counter()
    scene = mi.load_dict(convert(job["scene"], mi))
    load_seconds = time.perf_counter() - t0

    times = []
    cpu_times = []
    shape = None
    for k, seed in enumerate(job["seeds"]):
        t0, c0 = time.perf_counter(), time.process_time()
        img = mi.render(scene, spp=int(job["spp"]), seed=int(seed))
        dr.eval(img)
        dr.sync_thread()
        times.append(time.perf_counter() - t0)
        cpu_times.append(time.process_time() - c0)
        shape = img.shape
        # Scalar variants iterate directly; JIT variants (llvm, cuda) element by element after
        # evaluation (no numpy needed; images are small).
        data = array.array("f", list(img.array))
        if sys.byteorder != "little":
            data.byteswap()
        with open(os.path.join(out, f"image_{k}.f32"), "wb") as f:
            data.tofile(f)

    height, width = shape[0], shape[1]
    channels = shape[2] if len(shape) > 2 else 1
    result = {
        "version": mi.__version__,
        "variant": variant,
        "width": width,
        "height": height,
        "channels": channels,
        "load_seconds": load_seconds,
        "render_seconds": times,
        "render_cpu_seconds": cpu_times,
    }
    with open(os.path.join(out, "result.json"), "w", encoding="utf-8") as f:
        json.dump(result, f)


if __name__ == "__main__":
    main()
