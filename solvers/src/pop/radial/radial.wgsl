// A point light's radial octahedral grid on the GPU (f32), the twin of `RadialPop::step` in
// `pop/radial.rs`: one thread per (cell, channel), the same layout and the same arithmetic in
// the same order. The host wrapper is `radial/gpu.rs`; `Params` mirrors its `#[repr(C)]
// RadialParams` and the bindings its `SPEC` (checked by `tests/kernel_contract.rs`). Cell =
// texel + na2 * shell, slot = cell * nc + ch, with
//   state   [slot][Q, a]                          (lin / lout, ping-pong)
//   links   [slot][T x6, gamma x6]  out, in, lateral 0-3 (this cell as the source; host)
//   frac    [slot][front, side, back]             (of the current state)
//   acc     [slot][phi, J]
//   loss    [slot][absorbed, escaped]             (summed over the steps)
//   topo    [texel][nb x4, rev x4, antipode]      (u32)
//   weight  [cell] dr / V
//
// One step is `fractions_step` (the Eq 3 fractions of every lit cell and what its links
// absorb or let escape through r_max, added to its own loss accumulator: no reduction per
// step) then `gather` (the 6-neighbour gather, Eqs 2, 4-6, and phi, J). At checkpoints
// `reduce_a` / `reduce_b` sum, per (shell, channel) workgroup in a fixed order, the loss
// accumulators, the power in flight and the visits (sum of phi / weight = sum over the steps
// of Q) into one of two halves of `partials`: the host reads both (the step before the
// checkpoint and the checkpoint itself: the ratio rho and the last step's losses of the
// geometric tail) and adds the shells in shell order in f64. No atomics, no pow.

struct Params {
    // Texels per shell (N_a^2).
    na2: u32,
    // Shells.
    nr: u32,
    // Channels.
    nc: u32,
    // na2 * nr * nc.
    slots: u32,
    // Threads per dispatch row (x workgroups * 64).
    row: u32,
    // Workgroups of `reduce_*` (nr * nc).
    groups: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> lin: array<f32>;
@group(0) @binding(2) var<storage, read_write> lout: array<f32>;
@group(0) @binding(3) var<storage, read> links: array<f32>;
@group(0) @binding(4) var<storage, read_write> frac: array<f32>;
@group(0) @binding(5) var<storage, read_write> acc: array<f32>;
@group(0) @binding(6) var<storage, read_write> loss: array<f32>;
@group(0) @binding(7) var<storage, read> topo: array<u32>;
@group(0) @binding(8) var<storage, read> weight: array<f32>;
@group(0) @binding(9) var<storage, read_write> partials: array<f32>;

const FRAC_1_SQRT_2: f32 = 0.70710678118654752;

var<workgroup> red: array<vec4<f32>, 64>;

// G(mu, a) of kernel.rs `cumulative` (as in pop.wgsl): a clamped to [0, 1], no 0/0.
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

fn slot_of(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * P.row;
}

@compute @workgroup_size(64, 1, 1)
fn fractions_step(@builtin(global_invocation_id) gid: vec3<u32>) {
    let slot = slot_of(gid);
    if (slot >= P.slots) {
        return;
    }
    let q = lin[slot * 2u];
    if (q == 0.0) {
        return;
    }
    let f = fractions(lin[slot * 2u + 1u]);
    frac[slot * 3u] = f.x;
    frac[slot * 3u + 1u] = f.y;
    frac[slot * 3u + 2u] = f.z;
    let k = (slot / P.nc) / P.na2;
    let lk = slot * 12u;
    let tout = links[lk];
    var absorbed = q * f.x * (1.0 - tout);
    if (k + 1u == P.nr) {
        loss[slot * 2u + 1u] = loss[slot * 2u + 1u] + q * f.x * tout;
    }
    absorbed = absorbed + q * f.z * (1.0 - links[lk + 1u]);
    for (var s = 2u; s < 6u; s = s + 1u) {
        absorbed = absorbed + q * f.y * (1.0 - links[lk + s]);
    }
    loss[slot * 2u] = loss[slot * 2u] + absorbed;
}

@compute @workgroup_size(64, 1, 1)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let slot = slot_of(gid);
    if (slot >= P.slots) {
        return;
    }
    let ch = slot % P.nc;
    let cell = slot / P.nc;
    let t = cell % P.na2;
    let k = cell / P.na2;
    // Sources in the order of the CPU: (cell, fraction, link slot of the source).
    var src: array<vec3<u32>, 6>;
    var ns = 0u;
    if (k > 0u) {
        src[ns] = vec3<u32>(cell - P.na2, 0u, 0u);
        ns = ns + 1u;
    }
    if (k + 1u < P.nr) {
        src[ns] = vec3<u32>(cell + P.na2, 2u, 1u);
        ns = ns + 1u;
    }
    if (k == 0u) {
        src[ns] = vec3<u32>(topo[t * 9u + 8u], 2u, 1u);
        ns = ns + 1u;
    }
    for (var s = 0u; s < 4u; s = s + 1u) {
        src[ns] = vec3<u32>(topo[t * 9u + s] + P.na2 * k, 1u, 2u + topo[t * 9u + 4u + s]);
        ns = ns + 1u;
    }
    var sum = 0.0;
    var wa = 0.0;
    for (var i = 0u; i < ns; i = i + 1u) {
        let ss = src[i].x * P.nc + ch;
        let q = lin[ss * 2u];
        let lk = ss * 12u;
        let dq = q * frac[ss * 3u + src[i].y] * links[lk + src[i].z];
        sum = sum + dq;
        wa = wa + dq * lin[ss * 2u + 1u] * links[lk + 6u + src[i].z];
    }
    var a = 0.0;
    if (sum > 0.0) {
        a = min(max(wa / sum, 0.0), 1.0);
    }
    lout[slot * 2u] = sum;
    lout[slot * 2u + 1u] = a;
    let w = weight[cell];
    acc[slot * 2u] = acc[slot * 2u] + sum * w;
    acc[slot * 2u + 1u] = acc[slot * 2u + 1u] + sum * a * w;
}

// One workgroup per (shell k, channel ch), k = group / nc: each thread over a fixed stride of
// texels, then a fixed tree; partials[half][group][absorbed, escaped, in flight, visits].
fn reduce_into(lid: u32, group: u32, half: u32) {
    let k = group / P.nc;
    let ch = group % P.nc;
    var s = vec4<f32>(0.0);
    for (var t = lid; t < P.na2; t = t + 64u) {
        let cell = k * P.na2 + t;
        let slot = cell * P.nc + ch;
        s = s + vec4<f32>(loss[slot * 2u], loss[slot * 2u + 1u], lin[slot * 2u], acc[slot * 2u] / weight[cell]);
    }
    red[lid] = s;
    for (var stride = 32u; stride > 0u; stride = stride >> 1u) {
        workgroupBarrier();
        if (lid < stride) {
            red[lid] = red[lid] + red[lid + stride];
        }
    }
    if (lid == 0u) {
        let o = (half * P.groups + group) * 4u;
        partials[o] = red[0].x;
        partials[o + 1u] = red[0].y;
        partials[o + 2u] = red[0].z;
        partials[o + 3u] = red[0].w;
    }
}

@compute @workgroup_size(64, 1, 1)
fn reduce_a(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    reduce_into(lid, wid.x, 0u);
}

@compute @workgroup_size(64, 1, 1)
fn reduce_b(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    reduce_into(lid, wid.x, 1u);
}
