// FLD Algorithm 1 on the GPU (f32): red-black SOR passes with FLD Eqs 32-37, the boundary-layer
// D update and the RMS residual reduced on the GPU. The host wrapper is `fld/gpu.rs`; `Params`
// mirrors its `#[repr(C)] GpuParams` and the bindings its `SPEC` (checked by
// `tests/kernel_contract.rs`).
//
// requires: limiter.wgsl (the flux limiter and the LIMITER override; `SPEC` prepends it).
//
// Layout (same as the CPU kernel, see `fld/cpu.rs`): each field holds two packed
// checkerboards, colour c at offset c * plen. Colour c keeps, per row (j, k), the voxels
// i = 2m + s with s = (c + j + k) mod 2 at position m of a row of h values. The
// x-neighbours of (m, row) are entries m + s - 1 and m + s of the other colour's row; its
// y/z-neighbours are entry m of the adjacent rows of the other colour.
//
// Stopping: `state.done` is set by `reduce` once the residual is below the tolerance (or not
// finite); every kernel then returns at once, so the host may record more iterations than
// needed and read back only every few of them.

struct Params {
    nx: u32,
    ny: u32,
    nz: u32,
    h: u32,
    plen: u32,
    color: u32,
    // Residual-counted voxels: lo <= i <= hi_x, lo <= j <= hi_y, lo <= k <= hi_z.
    lo: u32,
    hi_x: u32,
    hi_y: u32,
    hi_z: u32,
    boundary_count: u32,
    boundary_row: u32,
    partials_per_color: u32,
    chunk: u32,
    _pad0: u32,
    _pad1: u32,
    omega: f32,
    one_minus_omega: f32,
    inv_2dl: f32,
    inv_dl2: f32,
    floor: f32,
    theta: f32,
    one_minus_theta: f32,
    larsen_n: f32,
    tolerance: f32,
    inv_residual_count: f32,
    _pad2: f32,
    _pad3: f32,
}

struct State {
    // Iterations completed (residual computed).
    iter: u32,
    // 0 running, 1 converged, 2 non-finite residual.
    done: u32,
    _pad0: u32,
    _pad1: u32,
    // Residual of iteration `iter` at index iter % chunk.
    residuals: array<f32>,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read_write> phi: array<f32>;
@group(0) @binding(2) var<storage, read_write> dcoef: array<f32>;
@group(0) @binding(3) var<storage, read> sig: array<f32>;
@group(0) @binding(4) var<storage, read> absorb: array<f32>;
@group(0) @binding(5) var<storage, read> src: array<f32>;
@group(0) @binding(6) var<storage, read_write> partials: array<f32>;
@group(0) @binding(7) var<storage, read_write> state: State;
@group(0) @binding(8) var<storage, read> boundary: array<u32>;

var<workgroup> wg_done: u32;
var<workgroup> red: array<f32, 256>;

// Packed index (colour offset included) of natural voxel (i, j, k).
fn packed(i: u32, j: u32, k: u32) -> u32 {
    let c = (i + j + k) & 1u;
    return c * P.plen + (k * P.ny + j) * P.h + i / 2u;
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

// D on the boundary layer (FLD only): F(R)/sigma with one-sided gradients where a neighbour is
// outside the grid, under-relaxed by theta (see the `fld` module docs).
@compute @workgroup_size(64, 1, 1)
fn boundary_d(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    if (finished(lid)) {
        return;
    }
    let t = gid.x + gid.y * P.boundary_row;
    if (t >= P.boundary_count) {
        return;
    }
    let n = boundary[t];
    let i = n % P.nx;
    let j = (n / P.nx) % P.ny;
    let k = n / (P.nx * P.ny);
    let x = span(i, P.nx);
    let y = span(j, P.ny);
    let z = span(k, P.nz);
    let g = vec3<f32>(
        (phi[packed(x.y, j, k)] - phi[packed(x.x, j, k)]) * P.inv_2dl * (2.0 / f32(x.y - x.x)),
        (phi[packed(i, y.y, k)] - phi[packed(i, y.x, k)]) * P.inv_2dl * (2.0 / f32(y.y - y.x)),
        (phi[packed(i, j, z.y)] - phi[packed(i, j, z.x)]) * P.inv_2dl * (2.0 / f32(z.y - z.x)),
    );
    let q = packed(i, j, k);
    let d = diffusion(g, sig[q], phi[q], P.floor, P.larsen_n);
    dcoef[q] = P.theta * d + P.one_minus_theta * dcoef[q];
}

// One colour pass (P.color) over the interior: FLD Eqs 34, 35, 33 (D), 32 (phi'), 36 (SOR,
// projected onto phi >= 0) and 37 (residual before the update). Writes the workgroup's sum
// of squared residuals to `partials`.
// 32 packed voxels of a row (128 contiguous bytes per field) by 8 rows; 256 threads.
@compute @workgroup_size(32, 8, 1)
fn sweep(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    if (finished(lid)) {
        return;
    }
    let c = P.color;
    let m = gid.x;
    let j = gid.y;
    let k = gid.z;
    let s = (c + j + k) & 1u;
    let i = 2u * m + s;
    var r2 = 0.0;
    if (m < P.h && i >= 1u && i + 1u < P.nx && j >= 1u && j + 1u < P.ny && k >= 1u && k + 1u < P.nz) {
        let row = (k * P.ny + j) * P.h;
        let own = c * P.plen + row + m;
        let oth = (1u - c) * P.plen + row;
        let slab = P.ny * P.h;
        let n0 = oth + m + s - 1u;
        let n1 = oth + m + s;
        let n2 = oth - P.h + m;
        let n3 = oth + P.h + m;
        let n4 = oth - slab + m;
        let n5 = oth + slab + m;
        let p0 = phi[n0];
        let p1 = phi[n1];
        let p2 = phi[n2];
        let p3 = phi[n3];
        let p4 = phi[n4];
        let p5 = phi[n5];
        let d0 = dcoef[n0];
        let d1 = dcoef[n1];
        let d2 = dcoef[n2];
        let d3 = dcoef[n3];
        let d4 = dcoef[n4];
        let d5 = dcoef[n5];
        let phi_p = phi[own];
        var d_p = dcoef[own];
        if (LIMITER != 0u) {
            let g = vec3<f32>(p1 - p0, p3 - p2, p5 - p4) * P.inv_2dl;
            let d = diffusion(g, sig[own], phi_p, P.floor, P.larsen_n);
            d_p = P.theta * d + P.one_minus_theta * d_p;
            dcoef[own] = d_p;
        }
        let sum_phi = p0 + p1 + p2 + p3 + p4 + p5;
        let sum_dphi = d0 * p0 + d1 * p1 + d2 * p2 + d3 * p3 + d4 * p4 + d5 * p5;
        let sum_d = d0 + d1 + d2 + d3 + d4 + d5;
        let num = src[own] + 0.5 * (d_p * sum_phi + sum_dphi);
        let den = absorb[own] + 0.5 * (6.0 * d_p + sum_d);
        let res = (num - phi_p * den) * P.inv_dl2;
        let counted = i >= P.lo && i <= P.hi_x && j >= P.lo && j <= P.hi_y && k >= P.lo && k <= P.hi_z;
        r2 = select(0.0, res * res, counted);
        let updated = P.omega * (num / den) + P.one_minus_omega * phi_p;
        // Projection onto phi >= 0; NaN passes through (the comparison is false).
        phi[own] = select(updated, 0.0, updated < 0.0);
    }
    red[lid] = r2;
    reduce_workgroup(lid);
    if (lid == 0u) {
        let wg = wid.x + nwg.x * (wid.y + nwg.y * wid.z);
        partials[c * P.partials_per_color + wg] = red[0];
    }
}

// Sums both colours' partials in a fixed order, stores the normalised RMS residual of this
// iteration and sets `done` when it is below the tolerance or not finite.
@compute @workgroup_size(256, 1, 1)
fn reduce(@builtin(local_invocation_index) lid: u32) {
    if (finished(lid)) {
        return;
    }
    var acc = 0.0;
    let total = 2u * P.partials_per_color;
    for (var t = lid; t < total; t = t + 256u) {
        acc = acc + partials[t];
    }
    red[lid] = acc;
    reduce_workgroup(lid);
    if (lid == 0u) {
        let r = sqrt(red[0] * P.inv_residual_count);
        let it = state.iter;
        state.residuals[it % P.chunk] = r;
        state.iter = it + 1u;
        // Infinity or NaN: all exponent bits set (no isnan in WGSL; compilers may fold x != x).
        if ((bitcast<u32>(r) & 0x7f800000u) == 0x7f800000u) {
            state.done = 2u;
        } else if (r < P.tolerance) {
            state.done = 1u;
        }
    }
}
