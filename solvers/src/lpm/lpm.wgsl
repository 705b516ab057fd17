// Light propagation maps on the GPU (f32), the twin of `lpm/cpu.rs` (host code `lpm/gpu.rs`;
// `Params` mirrors its `#[repr(C)] GpuParams`, the bindings its `SPEC`, both checked by
// `tests/kernel_contract.rs`). One order is, per face f = 0..5: `sweep` (one thread per
// (direction k of the face, ray r)), then `collect` (one thread per voxel); then `reduce`
// (one workgroup) forms the order's power tallies and the stopping test.
//
// Race freedom without atomics (spec D17, "class-slotted T"): the sub-segment j of slab z of
// direction k maps the ray lattice onto slab z by a shift (a bijection), so the word
// tbuf[(k * slots + j) * nv + v] has exactly one writer per sweep: the ray whose shifted
// position in that sub-segment is v. `collect` sums T_k = sum_j tbuf[k, j, v] for j < the
// slab's sub-segment count (in j order, from zero: the CPU's accumulation order), then the
// directions k = 0, 1, ... in the CPU's order; it writes only voxel v's words. `reduce`
// sums in a fixed order (strided per thread, then a tree). Nothing is ever written by two
// threads of one dispatch, so results are deterministic.
//
// Slice streaming (D19): each face's sweep axis is cut into slices of S slabs; per slice
// `sweep` marches the rays through its slabs, starting from the ray radiances and tallies
// the previous slice left in `rayt`, and `collect` gathers the slice's voxels. tbuf holds one
// slice in the layout vl = b + nb * (c + nc * (z - z0)) (z the sweep step). The operations
// per ray and per voxel are those of the unstreamed sweep, in the same order.
//
// Voxel v = x + nx * (y + ny * z). Buffers: U (6 cones x nv) ping-pong as uprev/ucur;
// rayt = [2 tally words per (direction, ray) of all faces (raw sums between slices, times
// A|Omega| after the last), then the ray radiance per (direction of the face, ray)];
// stats = [order, done, first unshot (f32 bits), 0, tallies ring (8 words per order),
// per-order fluence ring (nv words per order, f32 bits)].

struct Params {
    nx: u32,
    ny: u32,
    nz: u32,
    nv: u32,
    // Face of this dispatch (sweep, collect); 5 for reduce.
    face: u32,
    // Directions per face, m * m.
    per: u32,
    // T slots per direction (the most sub-segments of one slab, <= 3).
    slots: u32,
    // Rays of this face (nb * nc).
    rays: u32,
    // Most rays of any face (stride of the ray tallies).
    max_rays: u32,
    // 0 zero, 1 open, 2 periodic (D12).
    wrap: u32,
    // I buffers: 1 or 6.
    d_i: u32,
    // 1: stop when the unshot power <= rel * that of order 0.
    converge: u32,
    // Orders per tallies ring.
    ring: u32,
    // Orders per fluence ring (1 unless the per-order fluence is kept).
    phi_ring: u32,
    // Threads per dispatch row of sweep and of collect (x workgroups * 64).
    row: u32,
    crow: u32,
    rel: f32,
    h3: f32,
    // Series threshold of phis (0.5 in f32).
    ts: f32,
    // The slice of this dispatch: sweep steps z0..z1 of the face (slice streaming, D19).
    z0: u32,
    z1: u32,
    // Words per (direction, slot) plane of tbuf (the largest slice's voxels).
    tstride: u32,
    // 1 when the slice starts (z0 = 0) / ends (z1 = the axis length) the face's sweep.
    first: u32,
    last: u32,
    // c > 0 when every cone's weight is c * wphi (isotropic: 1 / 4 pi), else 0.
    iso: f32,
}

struct Seg {
    // Lateral offsets (absolute, not reduced) and length (times h and the path factor).
    ob: i32,
    oc: i32,
    len: f32,
    pad: f32,
}

struct Dir {
    // Index into `starts` of slab 0 of this direction.
    start_base: u32,
    // Boundary radiance (order 0).
    l_bc: f32,
    // A * |Omega| (tally weight).
    w: f32,
    // A * |Omega| / h^3 (fluence weight).
    wphi: f32,
    // A * dl * path / cos * |Omega|: emitted power per unit sum of U.
    emit: f32,
    // A * F^{i,d} / (h^3 |Omega^d|) for the six cones.
    wu: array<f32, 6>,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> segs: array<Seg>;
@group(0) @binding(2) var<storage, read> starts: array<u32>;
@group(0) @binding(3) var<storage, read> dirs: array<Dir>;
@group(0) @binding(4) var<storage, read> sigma_t: array<f32>;
@group(0) @binding(5) var<storage, read> sigma_s: array<f32>;
@group(0) @binding(6) var<storage, read> uprev: array<f32>;
@group(0) @binding(7) var<storage, read_write> ucur: array<f32>;
@group(0) @binding(8) var<storage, read_write> tbuf: array<f32>;
@group(0) @binding(9) var<storage, read_write> intensity: array<f32>;
@group(0) @binding(10) var<storage, read_write> phi: array<f32>;
@group(0) @binding(11) var<storage, read_write> vox: array<f32>;
@group(0) @binding(12) var<storage, read_write> rayt: array<f32>;
@group(0) @binding(13) var<storage, read_write> stats: array<u32>;

const CONE: f32 = 2.0943951023931953; // 4 pi / 6

// The lateral axes (b, c) of sweep axis a, as `directions::lateral_axes`.
fn lateral(a: u32) -> vec2<u32> {
    if (a == 0u) {
        return vec2<u32>(1u, 2u);
    }
    if (a == 1u) {
        return vec2<u32>(0u, 2u);
    }
    return vec2<u32>(0u, 1u);
}

fn dim(axis: u32) -> u32 {
    return select(select(P.nz, P.ny, axis == 1u), P.nx, axis == 0u);
}

fn rem(x: i32, n: u32) -> u32 {
    let m = i32(n);
    return u32(((x % m) + m) % m);
}

// e^{-tau} for tau >= 0 as `cpu::exp_neg_f32`: clamp to 80, k = round(x log2 e), two-constant
// Cody-Waite ln 2, degree-7 Taylor polynomial, 2^k from its bits.
fn exp_neg(tau: f32) -> f32 {
    let x = -min(tau, 80.0);
    let k = round(x * 1.4426950408889634);
    let r = (x - k * 0.693359375) + k * 2.12194440e-4;
    let p = 1.0 + r * (1.0 + r * (0.5 + r * (1.0 / 6.0 + r * (1.0 / 24.0
        + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))));
    return p * bitcast<f32>(u32(i32(k) + 127) << 23u);
}

// (E, phi1, phi2) of optical depth tau as `cpu::phis` in f32 (series below ts).
fn phis(tau: f32, ts: f32) -> vec3<f32> {
    let f1s = 1.0 - tau * (1.0 / 2.0 - tau * (1.0 / 6.0 - tau * (1.0 / 24.0 - tau * (1.0 / 120.0
        - tau * (1.0 / 720.0 - tau * (1.0 / 5040.0 - tau * (1.0 / 40320.0)))))));
    let f2s = 1.0 / 2.0 - tau * (1.0 / 6.0 - tau * (1.0 / 24.0 - tau * (1.0 / 120.0
        - tau * (1.0 / 720.0 - tau * (1.0 / 5040.0 - tau * (1.0 / 40320.0
        - tau * (1.0 / 362880.0)))))));
    if (tau < ts) {
        return vec3<f32>(1.0 - tau * f1s, f1s, f2s);
    }
    let e = exp_neg(tau);
    let inv = 1.0 / tau;
    return vec3<f32>(e, (1.0 - e) * inv, (tau - 1.0 + e) * inv * inv);
}

fn is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// One ray of one direction of face P.face through the grid (LPM Eq 3 in the exact form,
// the deposit of Eq 6 as the exact integral of L, the wrap of Fig 2 with rule D12).
@compute @workgroup_size(64)
fn sweep(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (stats[1] != 0u) {
        return;
    }
    let id = gid.x + gid.y * P.row;
    if (id >= P.per * P.rays) {
        return;
    }
    let k = id / P.rays;
    let r = id % P.rays;
    let face = P.face;
    let i = face * P.per + k;
    let a = face / 2u;
    let forward = (face % 2u) == 0u;
    let bc = lateral(a);
    let na = dim(a);
    let nb = dim(bc.x);
    let nc = dim(bc.y);
    let rb = r % nb;
    let rc = r / nb;
    let d = dirs[i];
    var l0 = 0.0;
    if (stats[0] == 0u) {
        l0 = d.l_bc;
    }
    let re = select(0.0, l0, P.wrap == 1u);
    let t = 2u * (i * P.max_rays + r);
    let ls = 12u * P.per * P.max_rays + k * P.max_rays + r;
    var l = l0;
    var injected = l0;
    var exited = 0.0;
    var pb = 0;
    var pc = 0;
    if (P.first == 0u) {
        // Carried from the previous slice: the radiance, the raw tallies, and the lateral
        // offsets of the last sub-segment of the previous slab (for the wrap events).
        l = rayt[ls];
        injected = rayt[t];
        exited = rayt[t + 1u];
        let sp = segs[starts[d.start_base + P.z0] - 1u];
        pb = sp.ob;
        pc = sp.oc;
    }
    let nv = P.nv;
    for (var z = P.z0; z < P.z1; z = z + 1u) {
        let slab = select(na - 1u - z, z, forward);
        let s0 = starts[d.start_base + z];
        let s1 = starts[d.start_base + z + 1u];
        for (var s = s0; s < s1; s = s + 1u) {
            let sg = segs[s];
            let vb = (rb + rem(sg.ob, nb)) % nb;
            let vc = (rc + rem(sg.oc, nc)) % nc;
            if (P.wrap != 2u) {
                // Rays that just crossed a side face leave and re-enter (Fig 2).
                let hit_b = sg.ob != pb && vb == select(nb - 1u, 0u, sg.ob > pb);
                let hit_c = sg.oc != pc && vc == select(nc - 1u, 0u, sg.oc > pc);
                if (hit_b || hit_c) {
                    exited = exited + l;
                    l = re;
                    injected = injected + re;
                }
            }
            pb = sg.ob;
            pc = sg.oc;
            var c = array<u32, 3>(0u, 0u, 0u);
            c[a] = slab;
            c[bc.x] = vb;
            c[bc.y] = vc;
            let v = c[0] + P.nx * (c[1] + P.ny * c[2]);
            let vl = vb + nb * (vc + nc * (z - P.z0));
            let u = uprev[face * nv + v];
            let len = sg.len;
            let f = phis(sigma_t[v] * len, P.ts);
            let l_out = l * f.x + u * len * f.y;
            tbuf[(k * P.slots + (s - s0)) * P.tstride + vl] = len * (l * f.y + u * len * f.z);
            l = l_out;
        }
    }
    if (P.last != 0u) {
        exited = exited + l;
        rayt[t] = d.w * injected;
        rayt[t + 1u] = d.w * exited;
    } else {
        rayt[t] = injected;
        rayt[t + 1u] = exited;
        rayt[ls] = l;
    }
}

// The collect of LPM Eq 4 at one voxel for the m * m directions of face P.face, in the CPU's
// order; face 0 starts U^cur, the order's fluence and the voxel tallies, face 5 adds the
// order's fluence to the total.
@compute @workgroup_size(64)
fn collect(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (stats[1] != 0u) {
        return;
    }
    // Thread id = the voxel's index vl = b + nb * (c + nc * (z - z0)) in the slice.
    let id = gid.x + gid.y * P.crow;
    let nv = P.nv;
    let face = P.face;
    let a = face / 2u;
    let na = dim(a);
    let bc = lateral(a);
    let nb = dim(bc.x);
    let nc = dim(bc.y);
    if (id >= (P.z1 - P.z0) * nb * nc) {
        return;
    }
    let z = P.z0 + id / (nb * nc);
    var xyz = array<u32, 3>(0u, 0u, 0u);
    xyz[a] = select(na - 1u - z, z, (face % 2u) == 0u);
    xyz[bc.x] = id % nb;
    xyz[bc.y] = (id / nb) % nc;
    let v = xyz[0] + P.nx * (xyz[1] + P.ny * xyz[2]);
    var fl = 0.0;
    var acc = array<f32, 6>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (var k = 0u; k < P.per; k = k + 1u) {
        let d = dirs[face * P.per + k];
        let s0 = starts[d.start_base + z];
        let s1 = starts[d.start_base + z + 1u];
        var g = 0.0;
        for (var s = s0; s < s1; s = s + 1u) {
            g = g + tbuf[(k * P.slots + (s - s0)) * P.tstride + id];
        }
        fl = fl + d.wphi * g;
        if (P.iso == 0.0) {
            for (var q = 0u; q < 6u; q = q + 1u) {
                acc[q] = acc[q] + d.wu[q] * g;
            }
        }
    }
    if (P.iso > 0.0) {
        // Rank-one F (isotropic): every cone gets c * the fluence sum, as on the CPU.
        for (var q = 0u; q < 6u; q = q + 1u) {
            acc[q] = P.iso * fl;
        }
    }
    let ss = sigma_s[v];
    let first = face == 0u;
    var total = 0.0;
    for (var q = 0u; q < 6u; q = q + 1u) {
        let du = ss * acc[q];
        let w = q * nv + v;
        if (first) {
            ucur[w] = du;
        } else {
            ucur[w] = ucur[w] + du;
        }
        if (P.d_i == 6u) {
            intensity[w] = intensity[w] + du;
        }
        total = total + du;
    }
    if (P.d_i == 1u) {
        intensity[v] = intensity[v] + total * (1.0 / 6.0);
    }
    let ring = 4u + 8u * P.ring + (stats[0] % P.phi_ring) * nv + v;
    var fp = fl;
    let dep = total * CONE;
    let ab = (sigma_t[v] - ss) * fl;
    if (first) {
        vox[2u * v] = dep;
        vox[2u * v + 1u] = ab;
    } else {
        fp = bitcast<f32>(stats[ring]) + fl;
        vox[2u * v] = vox[2u * v] + dep;
        vox[2u * v + 1u] = vox[2u * v + 1u] + ab;
    }
    stats[ring] = bitcast<u32>(fp);
    if (face == 5u) {
        phi[v] = phi[v] + fp;
    }
}

var<workgroup> red: array<array<f32, 10>, 256>;
var<workgroup> halt: u32;

// The order's tallies (injected, emitted, exited, absorbed, scattered) in a fixed summation
// order, the stopping test (D1) and the order count.
@compute @workgroup_size(256)
fn reduce(@builtin(local_invocation_index) t: u32) {
    if (t == 0u) {
        halt = stats[1];
    }
    if (workgroupUniformLoad(&halt) != 0u) {
        return;
    }
    let nv = P.nv;
    var q = array<f32, 10>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let nr = 6u * P.per * P.max_rays;
    for (var j = t; j < nr; j = j + 256u) {
        q[0] = q[0] + rayt[2u * j];
        q[1] = q[1] + rayt[2u * j + 1u];
    }
    for (var v = t; v < nv; v = v + 256u) {
        q[2] = q[2] + vox[2u * v];
        q[3] = q[3] + vox[2u * v + 1u];
        for (var f = 0u; f < 6u; f = f + 1u) {
            q[4u + f] = q[4u + f] + uprev[f * nv + v];
        }
    }
    red[t] = q;
    workgroupBarrier();
    for (var s = 128u; s > 0u; s = s >> 1u) {
        if (t < s) {
            for (var c = 0u; c < 10u; c = c + 1u) {
                red[t][c] = red[t][c] + red[t + s][c];
            }
        }
        workgroupBarrier();
    }
    if (t == 0u) {
        var sum = red[0];
        var emitted = 0.0;
        for (var i = 0u; i < 6u * P.per; i = i + 1u) {
            emitted = emitted + dirs[i].emit * sum[4u + i / P.per];
        }
        let order = stats[0];
        let scattered = sum[2] * P.h3;
        let slot = 4u + 8u * (order % P.ring);
        stats[slot] = bitcast<u32>(sum[0]);
        stats[slot + 1u] = bitcast<u32>(emitted);
        stats[slot + 2u] = bitcast<u32>(sum[1]);
        stats[slot + 3u] = bitcast<u32>(sum[3] * P.h3);
        stats[slot + 4u] = bitcast<u32>(scattered);
        var first = bitcast<f32>(stats[2]);
        if (order == 0u) {
            first = scattered;
            stats[2] = bitcast<u32>(first);
        }
        let finite = is_finite(sum[0]) && is_finite(sum[1]) && is_finite(emitted)
            && is_finite(scattered);
        var done = 0u;
        if (!finite) {
            done = 2u;
        } else if (P.converge != 0u && scattered <= P.rel * first) {
            done = 1u;
        }
        stats[0] = order + 1u;
        stats[1] = done;
    }
}
