// Lattice-Boltzmann lighting on the GPU (f32): one thread per site pulls the 19 upstream
// post-collision densities (or the boundary inflow), collides with LB Eqs 4-6 and writes the
// 19 results to the other buffer (ping-pong). The host wrapper is `lbm/gpu.rs`; `Params`
// mirrors its `#[repr(C)] GpuParams` and the bindings its `SPEC` (checked by
// `tests/kernel_contract.rs`). Same layout and arithmetic order as `lbm/cpu.rs`:
// direction i of site (x, y, z) at ((z * 19 + i) * ny + y) * nx + x.
//
// `step_reduce` is `step` plus per-workgroup sums of (arriving density, outflow, removed
// absorption); `reduce` adds those partials in a fixed order into `totals` (checkpoints).

// Isotropic scattering (S_ij = w_i) or the 18x18 kernel from `table`.
override ISO: bool = true;

struct Params {
    nx: u32,
    ny: u32,
    nz: u32,
    sites: u32,
    // Threads per dispatch row (x workgroups * 256).
    row: u32,
    // 1: LB Eqs 5-6 re-emit the rest density (paper); 0: absorbed density is removed.
    reemit: u32,
    has_src: u32,
    // Workgroups of one step dispatch (number of partials).
    groups: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> fin: array<f32>;
@group(0) @binding(2) var<storage, read_write> fout: array<f32>;
@group(0) @binding(3) var<storage, read> ss: array<f32>;
@group(0) @binding(4) var<storage, read> sa: array<f32>;
@group(0) @binding(5) var<storage, read> emission: array<f32>;
// [0, 19): inflow per direction; [19, 19 + 361): S_ij at 19 + 19 * i + j.
@group(0) @binding(6) var<storage, read> table: array<f32>;
@group(0) @binding(7) var<storage, read_write> partials: array<f32>;
@group(0) @binding(8) var<storage, read_write> totals: array<f32>;

const CX = array<i32, 19>(0, 1, -1, 0, 0, 0, 0, 1, -1, 1, -1, 1, -1, 1, -1, 0, 0, 0, 0);
const CY = array<i32, 19>(0, 0, 0, 1, -1, 0, 0, 1, -1, -1, 1, 0, 0, 0, 0, 1, -1, 1, -1);
const CZ = array<i32, 19>(0, 0, 0, 0, 0, 1, -1, 0, 0, 0, 0, 1, -1, -1, 1, 1, -1, -1, 1);

var<workgroup> red: array<vec3<f32>, 256>;

fn inside(x: i32, y: i32, z: i32) -> bool {
    return x >= 0 && y >= 0 && z >= 0 && x < i32(P.nx) && y < i32(P.ny) && z < i32(P.nz);
}

fn weight(i: u32) -> f32 {
    return select(1.0 / 24.0, 1.0 / 12.0, i <= 6u);
}

// One site's step; returns (arriving density, outflow, removed absorption).
fn update(site: u32) -> vec3<f32> {
    let nx = P.nx;
    let ny = P.ny;
    let x = i32(site % nx);
    let y = i32((site / nx) % ny);
    let z = i32(site / (nx * ny));
    var f: array<f32, 19>;
    for (var i = 0u; i < 19u; i = i + 1u) {
        let sx = x - CX[i];
        let sy = y - CY[i];
        let sz = z - CZ[i];
        if (inside(sx, sy, sz)) {
            f[i] = fin[((u32(sz) * 19u + i) * ny + u32(sy)) * nx + u32(sx)];
        } else {
            f[i] = table[i];
        }
    }
    var m = 0.0;
    for (var i = 1u; i < 19u; i = i + 1u) {
        m = m + f[i];
    }
    let s_s = ss[site];
    let s_a = sa[site];
    var e = 0.0;
    if (P.has_src != 0u) {
        e = emission[site];
    }
    let keep = 1.0 - s_s - s_a;
    let rest = select(0.0, f[0], P.reemit != 0u);
    var iso = rest + e;
    if (ISO) {
        iso = s_s * m + rest + e;
    }
    var o: array<f32, 19>;
    o[0] = s_a * m;
    for (var i = 1u; i < 19u; i = i + 1u) {
        if (ISO) {
            o[i] = keep * f[i] + weight(i) * iso;
        } else {
            var acc = 0.0;
            for (var j = 1u; j < 19u; j = j + 1u) {
                acc = acc + table[19u + 19u * i + j] * f[j];
            }
            o[i] = keep * f[i] + s_s * acc + weight(i) * iso;
        }
    }
    var outflow = 0.0;
    for (var i = 0u; i < 19u; i = i + 1u) {
        fout[((u32(z) * 19u + i) * ny + u32(y)) * nx + u32(x)] = o[i];
        if (i > 0u && !inside(x + CX[i], y + CY[i], z + CZ[i])) {
            outflow = outflow + o[i];
        }
    }
    let absorbed = select(o[0], 0.0, P.reemit != 0u);
    return vec3<f32>(m + rest, outflow, absorbed);
}

@compute @workgroup_size(256, 1, 1)
fn step(@builtin(global_invocation_id) gid: vec3<u32>) {
    let site = gid.x + gid.y * P.row;
    if (site < P.sites) {
        update(site);
    }
}

@compute @workgroup_size(256, 1, 1)
fn step_reduce(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let site = gid.x + gid.y * P.row;
    var t = vec3<f32>(0.0);
    if (site < P.sites) {
        t = update(site);
    }
    red[lid] = t;
    for (var stride = 128u; stride > 0u; stride = stride >> 1u) {
        workgroupBarrier();
        if (lid < stride) {
            red[lid] = red[lid] + red[lid + stride];
        }
    }
    if (lid == 0u) {
        let wg = wid.x + wid.y * nwg.x;
        partials[3u * wg] = red[0].x;
        partials[3u * wg + 1u] = red[0].y;
        partials[3u * wg + 2u] = red[0].z;
    }
}

// Sums the partials of the last `step_reduce` in a fixed order into totals[0..3].
@compute @workgroup_size(256, 1, 1)
fn reduce(@builtin(local_invocation_index) lid: u32) {
    var acc = vec3<f32>(0.0);
    for (var w = lid; w < P.groups; w = w + 256u) {
        acc = acc + vec3<f32>(partials[3u * w], partials[3u * w + 1u], partials[3u * w + 2u]);
    }
    red[lid] = acc;
    for (var stride = 128u; stride > 0u; stride = stride >> 1u) {
        workgroupBarrier();
        if (lid < stride) {
            red[lid] = red[lid] + red[lid + stride];
        }
    }
    if (lid == 0u) {
        totals[0] = red[0].x;
        totals[1] = red[0].y;
        totals[2] = red[0].z;
    }
}
