// Principal-ordinates propagation on the GPU (f32): one ordinate's grid, one thread per cell.
// The host wrapper is `pop/gpu.rs`; `Params` mirrors its `#[repr(C)] GpuParams` and the
// bindings its `SPEC` (checked by `tests/kernel_contract.rs`). Same layout and the same
// arithmetic order as `pop/cpu.rs`: cell (i, j, k) is i + n (j + n k), channel ch of a cell
// at slot = cell * nc + ch, with
//   state  [slot][L, a]                      (lin / lout, ping-pong)
//   links  [slot][T+t1, T+t2, T+d, g+t1, g+t2, g+d, ghost]   (precomputed on the host)
//   frac   [slot][front, side, back]         (of the current state)
//   acc    [slot][phi, J, L_acc]
//   loss   [slot][absorbed, exit back, exit front, exit side]  (summed over the steps)
//   view   [ch] lobe factor of Eq 8, then [cell] u = d . (direction to the observer)
//
// One step is `fractions` (Eq 3 fractions of every lit cell and where its light goes) then
// `gather` (the 6-neighbour gather of Eqs 2, 4-6, the accumulation of Eqs 7-8). `reduce`
// (checkpoints only) sums the loss accumulators and the power in flight of one slice and one
// channel per workgroup in a fixed order; the host adds the slices in slice order. No atomics.
// There is no pow here: the Eq 4 factors g^(sigma_s z) are precomputed on the host with the
// branches of spec V16 (pow(0, 0) never evaluated).

struct Params {
    n: u32,
    nc: u32,
    cells: u32,
    plane: u32,
    // Threads per dispatch row (x workgroups * 64).
    row: u32,
    // 1: laterally periodic faces.
    periodic: u32,
    // 1: accumulate the Eq 8 radiance (an observer is set).
    has_view: u32,
    // Workgroups of `reduce` (n * nc).
    groups: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> lin: array<f32>;
@group(0) @binding(2) var<storage, read_write> lout: array<f32>;
@group(0) @binding(3) var<storage, read> links: array<f32>;
@group(0) @binding(4) var<storage, read_write> frac: array<f32>;
@group(0) @binding(5) var<storage, read_write> acc: array<f32>;
@group(0) @binding(6) var<storage, read_write> loss: array<f32>;
@group(0) @binding(7) var<storage, read> view: array<f32>;
@group(0) @binding(8) var<storage, read_write> partials: array<f32>;

const FRAC_1_SQRT_2: f32 = 0.70710678118654752;
const FOUR_PI: f32 = 12.566370614359172;
// The largest lobe parameter Eq 8 evaluates (spec D8, V16; kernel.rs A_MAX_VIEW).
const A_MAX_VIEW: f32 = 0.9999;

var<workgroup> red: array<vec4<f32>, 64>;
var<workgroup> red_flight: array<f32, 64>;

// G(mu, a) = (1 - a)(1 + mu) / (s (1 + a + s)), s = sqrt(1 + a^2 - 2 a mu) (kernel.rs
// `cumulative`). a is clamped to [0, 1]: at a = 1 the numerator is 0 and s = sqrt(2 - 2 mu) > 0
// for |mu| = 1/sqrt(2), so no 0/0; the denominator is >= s > 0 for every a in [0, 1].
fn cumulative(mu: f32, a_in: f32) -> f32 {
    let a = clamp(a_in, 0.0, 1.0);
    let s = sqrt(1.0 + a * a - (a + a) * mu);
    return (1.0 - a) * (1.0 + mu) / (s * (1.0 + a + s));
}

// (front, side, back) of Eq 3 (kernel.rs `fractions`).
fn fractions(a: f32) -> vec3<f32> {
    let gp = cumulative(FRAC_1_SQRT_2, a);
    let gm = cumulative(-FRAC_1_SQRT_2, a);
    return vec3<f32>(1.0 - gp, (gp - gm) * 0.25, gm);
}

// f_hg(mu, g) in the cancellation-free form (1 - g)(1 + g) / (4 pi d^(3/2)),
// d = (1 - g)^2 + 2 g (1 - mu), g clamped to [0, A_MAX_VIEW] so that d >= 1e-8 > 0 (kernel.rs
// `hg_view`; the expanded 1 + g^2 - 2 g mu cancels to <= 0 in f32).
fn hg_view(mu: f32, g_in: f32) -> f32 {
    let g = clamp(g_in, 0.0, A_MAX_VIEW);
    let d = (1.0 - g) * (1.0 - g) + (g + g) * (1.0 - mu);
    return (1.0 - g) * (1.0 + g) / (FOUR_PI * d * sqrt(d));
}

// The -1 neighbour of index i along a lateral axis, or -1 (cpu.rs `neighbour_minus`).
fn minus(i: u32) -> i32 {
    if (i > 0u) {
        return i32(i) - 1;
    }
    if (P.periodic != 0u && P.n > 1u) {
        return i32(P.n) - 1;
    }
    return -1;
}

// The +1 neighbour of index i along a lateral axis, or -1 (cpu.rs `neighbour_plus`).
fn plus(i: u32) -> i32 {
    if (i + 1u < P.n) {
        return i32(i) + 1;
    }
    if (P.periodic != 0u && P.n > 1u) {
        return 0;
    }
    return -1;
}

fn cell_index(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * P.row;
}

// Where fraction `f` of `l` goes over a link of transmittance t (t < 0: no neighbour, the
// light leaves through a vacuum ghost cell of transmittance `ghost`): (absorbed, exited).
fn go(l: f32, f: f32, t: f32, ghost: f32) -> vec2<f32> {
    if (t >= 0.0) {
        return vec2<f32>(l * f * (1.0 - t), 0.0);
    }
    return vec2<f32>(l * f * (1.0 - ghost), l * f * ghost);
}

@compute @workgroup_size(64, 1, 1)
fn fractions_step(@builtin(global_invocation_id) gid: vec3<u32>) {
    let cell = cell_index(gid);
    if (cell >= P.cells) {
        return;
    }
    let n = P.n;
    let nc = P.nc;
    let i = cell % n;
    let j = (cell / n) % n;
    let k = cell / P.plane;
    let open = P.periodic == 0u;
    let im = minus(i);
    let jm = minus(j);
    for (var ch = 0u; ch < nc; ch = ch + 1u) {
        let slot = cell * nc + ch;
        let l = lin[slot * 2u];
        if (l == 0.0) {
            // Nothing to send: the gather multiplies the (stale, finite) fractions by L = 0.
            continue;
        }
        let f = fractions(lin[slot * 2u + 1u]);
        frac[slot * 3u] = f.x;
        frac[slot * 3u + 1u] = f.y;
        frac[slot * 3u + 2u] = f.z;
        let lk = slot * 7u;
        let ghost = links[lk + 6u];
        // absorbed, exit back, exit front, exit side
        var s = vec4<f32>(0.0);
        // Along d.
        var t = -1.0;
        if (k + 1u < n) {
            t = links[lk + 2u];
        }
        var r = go(l, f.x, t, ghost);
        s.x = s.x + r.x;
        s.z = s.z + r.y;
        t = -1.0;
        if (k > 0u) {
            t = links[(slot - P.plane * nc) * 7u + 2u];
        }
        r = go(l, f.z, t, ghost);
        s.x = s.x + r.x;
        s.y = s.y + r.y;
        // Lateral.
        t = -1.0;
        if (!(open && i + 1u == n)) {
            t = links[lk];
        }
        r = go(l, f.y, t, ghost);
        s.x = s.x + r.x;
        s.w = s.w + r.y;
        t = -1.0;
        if (!(open && j + 1u == n)) {
            t = links[lk + 1u];
        }
        r = go(l, f.y, t, ghost);
        s.x = s.x + r.x;
        s.w = s.w + r.y;
        t = -1.0;
        if (im >= 0) {
            t = links[((u32(im) + n * (j + n * k)) * nc + ch) * 7u];
        }
        r = go(l, f.y, t, ghost);
        s.x = s.x + r.x;
        s.w = s.w + r.y;
        t = -1.0;
        if (jm >= 0) {
            t = links[((i + n * (u32(jm) + n * k)) * nc + ch) * 7u + 1u];
        }
        r = go(l, f.y, t, ghost);
        s.x = s.x + r.x;
        s.w = s.w + r.y;
        let q = slot * 4u;
        loss[q] = loss[q] + s.x;
        loss[q + 1u] = loss[q + 1u] + s.y;
        loss[q + 2u] = loss[q + 2u] + s.z;
        loss[q + 3u] = loss[q + 3u] + s.w;
    }
}

@compute @workgroup_size(64, 1, 1)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let cell = cell_index(gid);
    if (cell >= P.cells) {
        return;
    }
    let n = P.n;
    let nc = P.nc;
    let plane = P.plane;
    let i = cell % n;
    let j = (cell / n) % n;
    let k = cell / plane;
    // Sources, in the order of cpu.rs: (source cell, which fraction, link cell, link axis).
    var src_cell: array<u32, 6>;
    var src_which: array<u32, 6>;
    var src_link: array<u32, 6>;
    var ns = 0u;
    if (k > 0u) {
        src_cell[ns] = cell - plane;
        src_which[ns] = 0u;
        src_link[ns] = (cell - plane) * 8u + 2u;
        ns = ns + 1u;
    }
    if (k + 1u < n) {
        src_cell[ns] = cell + plane;
        src_which[ns] = 2u;
        src_link[ns] = cell * 8u + 2u;
        ns = ns + 1u;
    }
    let im = minus(i);
    if (im >= 0) {
        let s = u32(im) + n * (j + n * k);
        src_cell[ns] = s;
        src_which[ns] = 1u;
        src_link[ns] = s * 8u;
        ns = ns + 1u;
    }
    let ip = plus(i);
    if (ip >= 0) {
        src_cell[ns] = u32(ip) + n * (j + n * k);
        src_which[ns] = 1u;
        src_link[ns] = cell * 8u;
        ns = ns + 1u;
    }
    let jm = minus(j);
    if (jm >= 0) {
        let s = i + n * (u32(jm) + n * k);
        src_cell[ns] = s;
        src_which[ns] = 1u;
        src_link[ns] = s * 8u + 1u;
        ns = ns + 1u;
    }
    let jp = plus(j);
    if (jp >= 0) {
        src_cell[ns] = i + n * (u32(jp) + n * k);
        src_which[ns] = 1u;
        src_link[ns] = cell * 8u + 1u;
        ns = ns + 1u;
    }
    for (var ch = 0u; ch < nc; ch = ch + 1u) {
        var sum = 0.0;
        var wa = 0.0;
        for (var q = 0u; q < ns; q = q + 1u) {
            let ss = src_cell[q] * nc + ch;
            let l = lin[ss * 2u];
            // src_link packs (link cell, axis) as cell * 8 + axis.
            let lc = src_link[q] / 8u;
            let axis = src_link[q] % 8u;
            let link = (lc * nc + ch) * 7u;
            let dl = l * frac[ss * 3u + src_which[q]] * links[link + axis];
            sum = sum + dl;
            wa = wa + dl * lin[ss * 2u + 1u] * links[link + 3u + axis];
        }
        var a = 0.0;
        if (sum > 0.0) {
            a = min(max(wa / sum, 0.0), 1.0);
        }
        let slot = cell * nc + ch;
        lout[slot * 2u] = sum;
        lout[slot * 2u + 1u] = a;
        let q = slot * 3u;
        acc[q] = acc[q] + sum;
        acc[q + 1u] = acc[q + 1u] + sum * a;
        if (P.has_view != 0u) {
            acc[q + 2u] = acc[q + 2u] + sum * hg_view(view[nc + cell], a * view[ch]);
        }
    }
}

// One workgroup per (slice k, channel ch), k = group / nc: the loss accumulators and the L of
// the current state (`lin`) of that slice, each thread over a fixed stride of cells, then a
// fixed tree. partials[group][absorbed, back, front, side, in flight].
@compute @workgroup_size(64, 1, 1)
fn reduce(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let group = wid.x;
    let k = group / P.nc;
    let ch = group % P.nc;
    var s = vec4<f32>(0.0);
    var flight = 0.0;
    for (var c = lid; c < P.plane; c = c + 64u) {
        let slot = (k * P.plane + c) * P.nc + ch;
        s = s + vec4<f32>(loss[slot * 4u], loss[slot * 4u + 1u], loss[slot * 4u + 2u], loss[slot * 4u + 3u]);
        flight = flight + lin[slot * 2u];
    }
    red[lid] = s;
    red_flight[lid] = flight;
    for (var stride = 32u; stride > 0u; stride = stride >> 1u) {
        workgroupBarrier();
        if (lid < stride) {
            red[lid] = red[lid] + red[lid + stride];
            red_flight[lid] = red_flight[lid] + red_flight[lid + stride];
        }
    }
    if (lid == 0u) {
        let o = group * 5u;
        partials[o] = red[0].x;
        partials[o + 1u] = red[0].y;
        partials[o + 2u] = red[0].z;
        partials[o + 3u] = red[0].w;
        partials[o + 4u] = red_flight[0];
    }
}
