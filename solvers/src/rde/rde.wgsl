// The RDE's FTCS step on the GPU (f32): phi_out = phi_in + r B(phi_in), the three operators of
// `rde/mod.rs` behind the OP override, Dirichlet or Neumann (clamp-to-edge) walls behind
// NEUMANN, a global or per-voxel r behind LOCAL. The host wrapper is `rde/gpu.rs`; `Params`
// mirrors its `#[repr(C)] GpuParams` and the bindings its `SPEC` (checked by
// `tests/kernel_contract.rs`).
//
// Layout: natural (x fastest), the same as the CPU kernel (`rde/cpu.rs`). phi_in and phi_out are
// two distinct buffers swapped by the host every step (ping-pong, thesis Fig 4.2): no voxel
// reads a value written in the same step.
//
// `step` is the plain update (Frames runs, benchmarks). `step_res` is the same update plus the
// per-workgroup sum of squared residuals of FLD Eq 37 (before the update); `reduce` then sums
// the partials in a fixed order, stores R/j of this step and sets `done` below the tolerance.
// Once `done` is set, `step_res` and `reduce` return at once, so the host may record more steps
// than needed; the field of step n lies in buffer n mod 2.

// 0 conservative, 1 thesis Eq 4.8 with +, 2 thesis Eq 4.8 as printed (-).
override OP: u32 = 0u;
// 1: zero-flux walls (every voxel updated, neighbours clamped to the grid); 0: Dirichlet layer.
override NEUMANN: u32 = 0u;
// 1: per-voxel r from `rloc` (damped Jacobi); 0: the global P.r.
override LOCAL: u32 = 0u;

struct Params {
    nx: u32,
    ny: u32,
    nz: u32,
    // Residual-counted voxels: lo <= i <= hi_x, lo <= j <= hi_y, lo <= k <= hi_z.
    lo: u32,
    hi_x: u32,
    hi_y: u32,
    hi_z: u32,
    // Workgroups of one step (partials written by step_res).
    groups: u32,
    // Residual slots in the state buffer.
    chunk: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // Global r = c dt / dl.
    r: f32,
    // Tolerance on R/j.
    tolerance: f32,
    // 1 / number of residual-counted voxels.
    inv_count: f32,
    _pad3: f32,
}

struct State {
    // Steps completed with a residual.
    iter: u32,
    // 0 running, 1 converged, 2 non-finite residual.
    done: u32,
    _pad0: u32,
    _pad1: u32,
    // Residual of step `iter` at index iter % chunk.
    residuals: array<f32>,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> phi_in: array<f32>;
@group(0) @binding(2) var<storage, read_write> phi_out: array<f32>;
@group(0) @binding(3) var<storage, read> beta: array<f32>;
@group(0) @binding(4) var<storage, read> absorb: array<f32>;
@group(0) @binding(5) var<storage, read> src: array<f32>;
@group(0) @binding(6) var<storage, read> rloc: array<f32>;
@group(0) @binding(7) var<storage, read_write> partials: array<f32>;
@group(0) @binding(8) var<storage, read_write> state: State;

var<workgroup> wg_done: u32;
var<workgroup> red: array<f32, 256>;

fn idx(i: u32, j: u32, k: u32) -> u32 {
    return i + P.nx * (j + P.ny * k);
}

// Whether (i, j, k) is updated: Neumann every voxel, Dirichlet the interior.
fn updated(i: u32, j: u32, k: u32) -> bool {
    if (i >= P.nx || j >= P.ny || k >= P.nz) {
        return false;
    }
    if (NEUMANN == 1u) {
        return true;
    }
    return i >= 1u && i + 1u < P.nx && j >= 1u && j + 1u < P.ny && k >= 1u && k + 1u < P.nz;
}

// The bracket B = s - a phi + L(phi) of `rde/cpu.rs::bracket`, same arithmetic order; writes
// phi_out and returns B.
fn update(i: u32, j: u32, k: u32) -> f32 {
    let xm = select(i - 1u, i, i == 0u);
    let xp = min(i + 1u, P.nx - 1u);
    let ym = select(j - 1u, j, j == 0u);
    let yp = min(j + 1u, P.ny - 1u);
    let zm = select(k - 1u, k, k == 0u);
    let zp = min(k + 1u, P.nz - 1u);
    let c = idx(i, j, k);
    let n0 = idx(xm, j, k);
    let n1 = idx(xp, j, k);
    let n2 = idx(i, ym, k);
    let n3 = idx(i, yp, k);
    let n4 = idx(i, j, zm);
    let n5 = idx(i, j, zp);
    let p = phi_in[c];
    let p0 = phi_in[n0];
    let p1 = phi_in[n1];
    let p2 = phi_in[n2];
    let p3 = phi_in[n3];
    let p4 = phi_in[n4];
    let p5 = phi_in[n5];
    let bp = beta[c];
    let b0 = beta[n0];
    let b1 = beta[n1];
    let b2 = beta[n2];
    let b3 = beta[n3];
    let b4 = beta[n4];
    let b5 = beta[n5];
    let sum = p0 + p1 + p2 + p3 + p4 + p5;
    let lap = sum - 6.0 * p;
    var b: f32;
    if (OP == 0u) {
        let bsum = b0 + b1 + b2 + b3 + b4 + b5;
        let bphi = b0 * p0 + b1 * p1 + b2 * p2 + b3 * p3 + b4 * p4 + b5 * p5;
        b = src[c] - absorb[c] * p + 0.5 * (bp * lap + bphi - p * bsum);
    } else {
        let grad = (b1 - b0) * (p1 - p0) + (b3 - b2) * (p3 - p2) + (b5 - b4) * (p5 - p4);
        var g = 0.25 * grad;
        if (OP == 2u) {
            g = -g;
        }
        b = src[c] - absorb[c] * p + bp * lap + g;
    }
    var r = P.r;
    if (LOCAL == 1u) {
        r = rloc[c];
    }
    phi_out[c] = p + r * b;
    return b;
}

// Whether the done flag is set, read uniformly across the workgroup.
fn finished(lid: u32) -> bool {
    if (lid == 0u) {
        wg_done = state.done;
    }
    return workgroupUniformLoad(&wg_done) != 0u;
}

// Tree reduction of `red` over the workgroup; the sum ends in red[0].
fn reduce_workgroup(lid: u32) {
    for (var stride = 128u; stride > 0u; stride = stride >> 1u) {
        workgroupBarrier();
        if (lid < stride) {
            red[lid] = red[lid] + red[lid + stride];
        }
    }
    workgroupBarrier();
}

// 32 voxels of a row by 8 rows; 256 threads.
@compute @workgroup_size(32, 8, 1)
fn step(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (updated(gid.x, gid.y, gid.z)) {
        update(gid.x, gid.y, gid.z);
    }
}

@compute @workgroup_size(32, 8, 1)
fn step_res(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    if (finished(lid)) {
        return;
    }
    let i = gid.x;
    let j = gid.y;
    let k = gid.z;
    var r2 = 0.0;
    if (updated(i, j, k)) {
        let b = update(i, j, k);
        let counted = i >= P.lo && i <= P.hi_x && j >= P.lo && j <= P.hi_y && k >= P.lo && k <= P.hi_z;
        r2 = select(0.0, b * b, counted);
    }
    red[lid] = r2;
    reduce_workgroup(lid);
    if (lid == 0u) {
        partials[wid.x + nwg.x * (wid.y + nwg.y * wid.z)] = red[0];
    }
}

// Sums the partials in a fixed order, stores the normalised RMS residual of this step and sets
// `done` when it is below the tolerance or not finite. The residual is B/dl; the host folds
// 1/dl^2 into inv_count.
@compute @workgroup_size(256, 1, 1)
fn reduce(@builtin(local_invocation_index) lid: u32) {
    if (finished(lid)) {
        return;
    }
    var acc = 0.0;
    for (var t = lid; t < P.groups; t = t + 256u) {
        acc = acc + partials[t];
    }
    red[lid] = acc;
    reduce_workgroup(lid);
    if (lid == 0u) {
        let r = sqrt(red[0] * P.inv_count);
        let it = state.iter;
        state.residuals[it % P.chunk] = r;
        state.iter = it + 1u;
        // Infinity or NaN: all exponent bits set (no isnan in WGSL).
        if ((bitcast<u32>(r) & 0x7f800000u) == 0x7f800000u) {
            state.done = 2u;
        } else if (r < P.tolerance) {
            state.done = 1u;
        }
    }
}
