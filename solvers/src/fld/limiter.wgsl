// The flux limiters F(R) of FLD Table 2 in f32, shared by every FLD kernel: `fld.wgsl` (the
// red-black sweep) and `multigrid/multigrid.wgsl` (the multigrid transfers) each name this file
// in a `// requires:` line and their host specs prepend it (`concat!`), so the GPU has one
// definition of each limiter and of the Knudsen number around it. The CPU twin is `limiter.rs`
// (and the D updates of `cpu.rs` and `multigrid/mod.rs`).

// Which flux limiter (FLD Table 2): 0 CDA, 1 sum, 2 max, 3 Kershaw, 4 Larsen-n, 5 LP.
override LIMITER: u32 = 5u;

// F(R) of FLD Table 2, written so f32 neither overflows nor cancels. LP differs from the CPU's
// `fld/limiter.rs` (a rational minimax form and (R - 1)/R^2, no exp, since 2026-12-06): the GPU
// keeps the depth-10 continued fraction for R <= 2 and the closed form with the built-in exp.
fn limiter(r_in: f32, larsen_n: f32) -> f32 {
    let r = max(r_in, 0.0);
    switch LIMITER {
        case 1u: {
            return 1.0 / (3.0 + r);
        }
        case 2u: {
            return 1.0 / max(3.0, r);
        }
        case 3u: {
            // 2 / (3 + sqrt(9 + 4R^2)) with a scaled hypotenuse.
            let m = max(3.0, 2.0 * r);
            let a = 3.0 / m;
            let b = 2.0 * r / m;
            return 2.0 / (3.0 + m * sqrt(a * a + b * b));
        }
        case 4u: {
            let n = larsen_n;
            let m = max(3.0, r);
            let s = pow(3.0 / m, n) + pow(r / m, n);
            return 1.0 / (m * pow(s, 1.0 / n));
        }
        case 5u: {
            if (r <= 2.0) {
                // Levermore-Pomraning through its continued fraction (depth 10).
                let a = r * r;
                var a_prev = 1.0;
                var a_cur = 3.0;
                var b_prev = 0.0;
                var b_cur = 1.0;
                for (var k = 1u; k <= 10u; k = k + 1u) {
                    let bk = f32(2u * k + 3u);
                    let a_next = bk * a_cur + a * a_prev;
                    let b_next = bk * b_cur + a * b_prev;
                    a_prev = a_cur;
                    a_cur = a_next;
                    b_prev = b_cur;
                    b_cur = b_next;
                }
                return b_cur / a_cur;
            }
            let e = exp(-2.0 * r);
            let coth = (1.0 + e) / (1.0 - e);
            return (coth - 1.0 / r) / r;
        }
        default: {
            return 1.0 / 3.0;
        }
    }
}

// The two neighbours (x: lower, y: upper) of index i along an axis of n voxels for the
// gradient of FLD Eq 34: centred inside, one-sided on the Dirichlet layer; a difference over
// them is scaled by 2 / (y - x).
fn span(i: u32, n: u32) -> vec2<u32> {
    return vec2<u32>(select(i - 1u, 0u, i == 0u), min(i + 1u, n - 1u));
}

// D = F(R)/sigma with R = max(|g|, floor) / max(sigma phi, floor) (FLD Eqs 33-35), g the
// gradient of phi at the voxel.
fn diffusion(g: vec3<f32>, s: f32, phi_p: f32, floor: f32, larsen_n: f32) -> f32 {
    let r = max(sqrt(g.x * g.x + g.y * g.y + g.z * g.z), floor) / max(s * phi_p, floor);
    return limiter(r, larsen_n) / s;
}
