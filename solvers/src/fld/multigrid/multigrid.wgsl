// requires: ../limiter.wgsl (the flux limiter and the LIMITER override; `SPEC` prepends it).
//
// The FAS multigrid transfers of `multigrid/mod.rs` on the GPU (f32); the host is
// `multigrid/gpu.rs`, whose `MgParams` this `Params` mirrors and whose `SPEC` declares these
// bindings (both checked by `tests/kernel_contract.rs`). The smoother is `fld.wgsl` itself,
// one instance per level.
//
// One bind group per level l: its own fields (phi, dcoef, sig, absorb, src: the smoother's
// packed buffers; tmp: D recomputed from phi; res: the residual; base: R^phi of the current
// visit, or phi of the previous cycle on the finest level) and three fields of level l + 1
// (cphi, cres, cbase; dummies on the coarsest level). Every field is in the packed
// red-black layout of `fld.wgsl`; threads run over natural (i, j, k) and index through
// `pk` (this level) and `cpk` (level l + 1).

struct Params {
    nx: u32,
    ny: u32,
    nz: u32,
    h: u32,
    plen: u32,
    cnx: u32,
    cny: u32,
    cnz: u32,
    ch: u32,
    cplen: u32,
    // Per axis: 1 when this level is coarsened vertex-wise (coarse node c = node 2c), 0
    // cell-wise (coarse voxel c covers 2c - 1 and 2c); see `Axis` in `multigrid/mod.rs`.
    vertex_x: u32,
    vertex_y: u32,
    vertex_z: u32,
    // Residual-counted voxels of the stopping measure (finest level).
    lo: u32,
    hi_x: u32,
    hi_y: u32,
    hi_z: u32,
    // Workgroups of `norm` (partials to sum in `finish`).
    norm_groups: u32,
    // 1 when D depends on phi (FLD), 0 for CDA (D fixed, tmp = dcoef once at setup).
    fld: u32,
    _pad0: u32,
    inv_2dl: f32,
    inv_dl2: f32,
    dl2: f32,
    floor: f32,
    larsen_n: f32,
    _pad1: f32,
    _pad2: f32,
    _pad3: f32,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read_write> phi: array<f32>;
@group(0) @binding(2) var<storage, read_write> dcoef: array<f32>;
@group(0) @binding(3) var<storage, read> sig: array<f32>;
@group(0) @binding(4) var<storage, read> absorb: array<f32>;
@group(0) @binding(5) var<storage, read_write> src: array<f32>;
@group(0) @binding(6) var<storage, read_write> tmp: array<f32>;
@group(0) @binding(7) var<storage, read_write> res: array<f32>;
@group(0) @binding(8) var<storage, read_write> base: array<f32>;
@group(0) @binding(9) var<storage, read_write> cphi: array<f32>;
@group(0) @binding(10) var<storage, read_write> cres: array<f32>;
@group(0) @binding(11) var<storage, read_write> cbase: array<f32>;
@group(0) @binding(12) var<storage, read_write> partials: array<f32>;
@group(0) @binding(13) var<storage, read_write> sums: array<f32>;

var<workgroup> red: array<vec3<f32>, 256>;

// Packed index of voxel (i, j, k) of this level and of level l + 1.
fn pk(i: u32, j: u32, k: u32) -> u32 {
    return ((i + j + k) & 1u) * P.plen + (k * P.ny + j) * P.h + i / 2u;
}

fn cpk(i: u32, j: u32, k: u32) -> u32 {
    return ((i + j + k) & 1u) * P.cplen + (k * P.cny + j) * P.ch + i / 2u;
}

// The voxel counts of this level.
fn dims() -> vec3<u32> {
    return vec3<u32>(P.nx, P.ny, P.nz);
}

fn is_layer(i: u32, j: u32, k: u32, n: vec3<u32>) -> bool {
    return i == 0u || j == 0u || k == 0u || i + 1u == n.x || j + 1u == n.y || k + 1u == n.z;
}

// L(phi) of FLD Eq 32 times dl^2 (phi_p * den - num) at interior voxel (i, j, k), with the
// diffusion coefficients in `tmp`; neighbours summed in the CPU's order x-, x+, y-, y+, z-, z+.
fn apply_dl2(i: u32, j: u32, k: u32) -> f32 {
    var q: array<u32, 6>;
    q[0] = pk(i - 1u, j, k);
    q[1] = pk(i + 1u, j, k);
    q[2] = pk(i, j - 1u, k);
    q[3] = pk(i, j + 1u, k);
    q[4] = pk(i, j, k - 1u);
    q[5] = pk(i, j, k + 1u);
    var sphi = 0.0;
    var sdphi = 0.0;
    var sd = 0.0;
    for (var n = 0u; n < 6u; n = n + 1u) {
        let p = phi[q[n]];
        let d = tmp[q[n]];
        sphi = sphi + p;
        sdphi = sdphi + d * p;
        sd = sd + d;
    }
    let c = pk(i, j, k);
    let dp = tmp[c];
    let den = absorb[c] + 0.5 * (6.0 * dp + sd);
    let num = 0.5 * (dp * sphi + sdphi);
    return phi[c] * den - num;
}

// tmp = F(R(phi))/sigma (FLD Eqs 33-35) on every voxel of this level: centred differences
// inside, one-sided on the Dirichlet layer, as `fresh_d` of `multigrid/mod.rs`.
@compute @workgroup_size(8, 8, 4)
fn fresh_d(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (any(gid >= dims())) {
        return;
    }
    let i = gid.x;
    let j = gid.y;
    let k = gid.z;
    let x = span(i, P.nx);
    let y = span(j, P.ny);
    let z = span(k, P.nz);
    let g = vec3<f32>(
        (phi[pk(x.y, j, k)] - phi[pk(x.x, j, k)]) * P.inv_2dl * (2.0 / f32(x.y - x.x)),
        (phi[pk(i, y.y, k)] - phi[pk(i, y.x, k)]) * P.inv_2dl * (2.0 / f32(y.y - y.x)),
        (phi[pk(i, j, z.y)] - phi[pk(i, j, z.x)]) * P.inv_2dl * (2.0 / f32(z.y - z.x)),
    );
    let q = pk(i, j, k);
    tmp[q] = diffusion(g, sig[q], phi[q], P.floor, P.larsen_n);
}

// res = j - L(phi) (normalised units) inside, 0 on the Dirichlet layer; j = src / dl^2.
@compute @workgroup_size(8, 8, 4)
fn residual(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = dims();
    if (any(gid >= n)) {
        return;
    }
    let i = gid.x;
    let j = gid.y;
    let k = gid.z;
    let q = pk(i, j, k);
    if (is_layer(i, j, k, n)) {
        res[q] = 0.0;
        return;
    }
    res[q] = (src[q] - apply_dl2(i, j, k)) * P.inv_dl2;
}

// Coarse level (this level), after `restrict` from its parent and `fresh_d` on the restricted
// phi: the FAS right-hand side src = dl^2 (R(res) + L(R^phi)) inside (0 on the layer), and,
// for FLD, the smoother's D set to the D just computed.
@compute @workgroup_size(8, 8, 4)
fn coarse_rhs(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = dims();
    if (any(gid >= n)) {
        return;
    }
    let i = gid.x;
    let j = gid.y;
    let k = gid.z;
    let q = pk(i, j, k);
    if (P.fld != 0u) {
        dcoef[q] = tmp[q];
    }
    if (is_layer(i, j, k, n)) {
        src[q] = 0.0;
        return;
    }
    src[q] = res[q] * P.dl2 + apply_dl2(i, j, k);
}

// The smoother's D set to tmp (FLD, after a prolongation).
@compute @workgroup_size(8, 8, 4)
fn take_d(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (any(gid >= dims())) {
        return;
    }
    let q = pk(gid.x, gid.y, gid.z);
    dcoef[q] = tmp[q];
}

// Per-axis weights of the medium restriction R^ ("mean" in `Axis`) at coarse interior index
// c, term t: fine index (x) and weight (y; 0 for an unused term).
fn mean_w(vertex: u32, c: u32, t: u32) -> vec2<f32> {
    if (vertex != 0u) {
        return vec2<f32>(f32(2u * c + t - 1u), select(0.25, 0.5, t == 1u));
    }
    return vec2<f32>(f32(2u * c + min(t, 1u) - 1u), select(0.5, 0.0, t == 2u));
}

// Per-axis weights of the residual restriction (the transpose of the prolongation) at coarse
// interior index c, term t < 4.
fn fw_w(vertex: u32, c: u32, t: u32) -> vec2<f32> {
    if (vertex != 0u) {
        let w = array<f32, 4>(0.5, 1.0, 0.5, 0.0);
        return vec2<f32>(f32(2u * c + min(t, 2u) - 1u), w[t]);
    }
    let w = array<f32, 4>(0.25, 0.75, 0.75, 0.25);
    return vec2<f32>(f32(2u * c + t - 2u), w[t]);
}

// Fine index of coarse layer index c along an axis (n fine voxels, nc coarse): the nearest
// fine layer voxel when c is on the coarse layer, else the first fine voxel c covers.
fn layer_index(c: u32, nc: u32, n: u32, vertex: u32) -> u32 {
    if (c == 0u) {
        return 0u;
    }
    if (c + 1u == nc) {
        return n - 1u;
    }
    return select(2u * c - 1u, 2u * c, vertex != 0u);
}

// Over the voxels of level l + 1: cphi = cbase = R^phi (the medium's restriction; the coarse
// layer copies the nearest fine voxel) and cres = R(res) / 8 (full weighting; 0 on the layer).
@compute @workgroup_size(8, 8, 4)
fn restrict_down(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nc = vec3<u32>(P.cnx, P.cny, P.cnz);
    if (any(gid >= nc)) {
        return;
    }
    let ic = gid.x;
    let jc = gid.y;
    let kc = gid.z;
    let qc = cpk(ic, jc, kc);
    if (is_layer(ic, jc, kc, nc)) {
        let v = phi[pk(
            layer_index(ic, nc.x, P.nx, P.vertex_x),
            layer_index(jc, nc.y, P.ny, P.vertex_y),
            layer_index(kc, nc.z, P.nz, P.vertex_z),
        )];
        cphi[qc] = v;
        cbase[qc] = v;
        cres[qc] = 0.0;
        return;
    }
    var m = 0.0;
    for (var tk = 0u; tk < 3u; tk = tk + 1u) {
        let wk = mean_w(P.vertex_z, kc, tk);
        for (var tj = 0u; tj < 3u; tj = tj + 1u) {
            let wj = mean_w(P.vertex_y, jc, tj);
            for (var ti = 0u; ti < 3u; ti = ti + 1u) {
                let wi = mean_w(P.vertex_x, ic, ti);
                let w = wk.y * wj.y * wi.y;
                if (w != 0.0) {
                    m = m + w * phi[pk(u32(wi.x), u32(wj.x), u32(wk.x))];
                }
            }
        }
    }
    var r = 0.0;
    for (var tk = 0u; tk < 4u; tk = tk + 1u) {
        let wk = fw_w(P.vertex_z, kc, tk);
        for (var tj = 0u; tj < 4u; tj = tj + 1u) {
            let wj = fw_w(P.vertex_y, jc, tj);
            for (var ti = 0u; ti < 4u; ti = ti + 1u) {
                let wi = fw_w(P.vertex_x, ic, ti);
                let w = wk.y * wj.y * wi.y;
                if (w != 0.0) {
                    r = r + w * res[pk(u32(wi.x), u32(wj.x), u32(wk.x))];
                }
            }
        }
    }
    cphi[qc] = m;
    cbase[qc] = m;
    cres[qc] = r * 0.125;
}

// Prolongation weights of fine interior index i along an axis, term t < 2: coarse index (x)
// and weight (y; 0 for an unused term or a coarse layer index, whose correction is 0).
fn prolong_w(vertex: u32, i: u32, t: u32, nc: u32) -> vec2<f32> {
    var c: u32;
    var w: f32;
    if (vertex != 0u) {
        c = i / 2u + t * (i & 1u);
        w = select(select(0.0, 1.0, t == 0u), 0.5, (i & 1u) == 1u);
    } else {
        let h = (i + 1u) / 2u;
        if (t == 0u) {
            c = h;
            w = 0.75;
        } else {
            c = select(h + 1u, h - 1u, (i & 1u) == 1u);
            w = 0.25;
        }
    }
    if (c == 0u || c + 1u >= nc) {
        w = 0.0;
    }
    return vec2<f32>(f32(c), w);
}

// Over the interior of this level: phi += P(cphi - cbase) (trilinear in the node positions),
// projected onto phi >= 0 as the smoother's update is (NaN passes through).
@compute @workgroup_size(8, 8, 4)
fn prolong(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = dims();
    if (any(gid >= n) || is_layer(gid.x, gid.y, gid.z, n)) {
        return;
    }
    let i = gid.x;
    let j = gid.y;
    let k = gid.z;
    var s = 0.0;
    for (var tk = 0u; tk < 2u; tk = tk + 1u) {
        let wk = prolong_w(P.vertex_z, k, tk, P.cnz);
        for (var tj = 0u; tj < 2u; tj = tj + 1u) {
            let wj = prolong_w(P.vertex_y, j, tj, P.cny);
            for (var ti = 0u; ti < 2u; ti = ti + 1u) {
                let wi = prolong_w(P.vertex_x, i, ti, P.cnx);
                let w = wk.y * wj.y * wi.y;
                if (w != 0.0) {
                    let qc = cpk(u32(wi.x), u32(wj.x), u32(wk.x));
                    s = s + w * (cphi[qc] - cbase[qc]);
                }
            }
        }
    }
    let q = pk(i, j, k);
    let v = phi[q] + s;
    phi[q] = select(v, 0.0, v < 0.0);
}

// Finest level, end of a cycle: per workgroup, the sum of res^2 over the residual window, of
// (phi - base)^2 and of phi^2 over every voxel (the update norm of the error estimate), into
// `partials`; base = phi for the next cycle.
@compute @workgroup_size(8, 8, 4)
fn norm(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let i = gid.x;
    let j = gid.y;
    let k = gid.z;
    var v = vec3<f32>(0.0, 0.0, 0.0);
    if (all(gid < dims())) {
        let q = pk(i, j, k);
        let counted = i >= P.lo && i <= P.hi_x && j >= P.lo && j <= P.hi_y && k >= P.lo && k <= P.hi_z;
        let r = res[q];
        let p = phi[q];
        let d = p - base[q];
        v = vec3<f32>(select(0.0, r * r, counted), d * d, p * p);
        base[q] = p;
    }
    red[lid] = v;
    for (var stride = 128u; stride > 0u; stride = stride >> 1u) {
        workgroupBarrier();
        if (lid < stride) {
            red[lid] = red[lid] + red[lid + stride];
        }
    }
    if (lid == 0u) {
        let g = wid.x + nwg.x * (wid.y + nwg.y * wid.z);
        partials[3u * g] = red[0].x;
        partials[3u * g + 1u] = red[0].y;
        partials[3u * g + 2u] = red[0].z;
    }
}

// Sums the `norm` partials in a fixed order into sums[0..3] (read back by the host).
@compute @workgroup_size(256, 1, 1)
fn finish(@builtin(local_invocation_index) lid: u32) {
    var acc = vec3<f32>(0.0, 0.0, 0.0);
    for (var g = lid; g < P.norm_groups; g = g + 256u) {
        acc = acc + vec3<f32>(partials[3u * g], partials[3u * g + 1u], partials[3u * g + 2u]);
    }
    red[lid] = acc;
    for (var stride = 128u; stride > 0u; stride = stride >> 1u) {
        workgroupBarrier();
        if (lid < stride) {
            red[lid] = red[lid] + red[lid + stride];
        }
    }
    if (lid == 0u) {
        sums[0] = red[0].x;
        sums[1] = red[0].y;
        sums[2] = red[0].z;
    }
}
