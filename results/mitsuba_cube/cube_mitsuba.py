"""Issue 14's homogeneous cube (sigma_t 4, albedo 0.9, unit box, directional light
(0.3, 0.4, -1) of irradiance 2, orthographic 16x16 camera of width 1.1 from -y) in Mitsuba 3,
with the medium and integrator settings as arguments, so that each suspect can be switched
on its own. Prints the image mean and its standard error over K seeds, per max_depth.

usage: python cube_mitsuba.py VARIANT MEDIUM RR_DEPTH SPP K MAX_DEPTH...
  MEDIUM: grid (heterogeneous + 8^3 gridvolume, as scatterbench exports it; the centre
          voxel's sigma_t from $CENTRE, default 4),
          const (heterogeneous + constvolume), homog (homogeneous medium)
  MAX_DEPTH: Mitsuba's (ours + 1), -1 for unlimited
"""
import struct, sys, tempfile, os, math, time
import drjit as dr
import mitsuba as mi

variant, medium_kind, rr_depth, spp, K = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
depths = [int(d) for d in sys.argv[6:]] or [-1]
mi.set_variant(variant)
CENTRE = float(os.environ.get("CENTRE", "4"))  # sigma_t of the centre voxel (grid only)

n = 8
tmp = tempfile.mkdtemp()
vol = os.path.join(tmp, "sigma_t.vol")
with open(vol, "wb") as f:
    f.write(b"VOL" + bytes([3]) + struct.pack("<iiiii", 1, n, n, n, 1))
    f.write(struct.pack("<6f", 0, 0, 0, 1, 1, 1))
    sigma = [4.0] * n**3
    sigma[n // 2 + n * (n // 2 + n * (n // 2))] = CENTRE
    f.write(struct.pack(f"<{n**3}f", *sigma))

if medium_kind == "grid":
    med = {"type": "heterogeneous", "sigma_t": {"type": "gridvolume", "filename": vol, "use_grid_bbox": True, "filter_type": "nearest"}, "albedo": 0.9, "scale": 1.0}
elif medium_kind == "const":
    med = {"type": "heterogeneous", "sigma_t": {"type": "constvolume", "value": 4.0}, "albedo": 0.9, "scale": 1.0}
elif medium_kind == "homog":
    med = {"type": "homogeneous", "sigma_t": 4.0, "albedo": 0.9, "scale": 1.0}
else:
    sys.exit("medium: grid | const | homog")
med["phase"] = {"type": "isotropic"}

T = mi.ScalarTransform4f
w = 1.1
look = T().look_at(origin=[0.5, -1.5, 0.5], target=[0.5, 0.5, 0.5], up=[0, 0, 1]) @ T().scale([w / 2, w / 2, 1])
for depth in depths:
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": depth, "rr_depth": rr_depth},
        "sensor": {"type": "orthographic", "to_world": look, "near_clip": 1e-4, "far_clip": 1e4,
                   "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"},
                            "pixel_format": "rgb", "component_format": "float32"},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "cube": {"type": "cube", "to_world": T().translate([0.5, 0.5, 0.5]) @ T().scale(0.5),
                 "bsdf": {"type": "null"}, "interior": med},
        "light": {"type": "directional", "direction": [0.3, 0.4, -1.0], "irradiance": 2.0},
    })
    means = []
    t0 = time.perf_counter()
    for k in range(K):
        img = mi.render(scene, spp=spp, seed=1000 + k)
        a = list(img.array)
        means.append(sum(a[0::3]) / (len(a) // 3))
    m = sum(means) / K
    se = math.sqrt(sum((x - m) ** 2 for x in means) / (K - 1) / K)
    print(f"centre {CENTRE} {variant} {medium_kind} rr_depth={rr_depth} max_depth={depth} spp={spp}x{K}: mean {m:.6f} +- {se:.6f}  ({time.perf_counter() - t0:.1f} s)", flush=True)
