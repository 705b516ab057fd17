//! The thesis's finite-element steady RTE with Jacobi iterations (thesis Eqs 3.16–3.22) as a
//! negative control, in 2D and 3D on a periodic grid (thesis Fig 3.5).
//!
//! Hat functions in space and ψ ∈ {1, ω_x, ω_y(, ω_z)} in angle give, per voxel, the mass
//! tensor δ_d = ⊗_axes M(d_axis) with the 1D hat mass M = (1/6, 2/3, 1/6) (thesis Eq 3.21:
//! centre 8/27, corners 1/216 in 3D) and the transport tensor β^a_d = D(d_a) ⊗_{b≠a} M(d_b)
//! with D = (−1/2, 0, 1/2) (thesis Eq 3.18 for a = x: middle row (1/9)(−2, 0, 2)). Thesis
//! Eq 3.22's Jacobi update is
//!
//! x_j ← (81/(32π)) (1/(Kt∆)) (φe, 0, …) − (27/(24 Kt∆)) Σ_d (3 Σ_a β^a_d E_a, β^x_d φ, …)_{j+d}
//!        − (1/δ₀) Σ_{d≠0} δ_d x_{j+d},
//!
//! with 27/8 = 1/δ₀ in 3D (9/4 in 2D). **Decisions:** the three β_{k,l} the thesis calls
//! equal (its l. 3498) are the same stencil rotated per axis, as used here; the transport
//! prefactor 27/24 is kept in 2D as printed for 3D (it does not act on the mode that breaks
//! Jacobi). The consistent mass matrix alone makes Jacobi diverge: on a uniform field the
//! transport term vanishes (β^a is odd) and each iteration multiplies the field by
//! −(1 − δ₀)/δ₀ = −19/8 (3D) or −5/4 (2D), for every Kt (tests `c13_…`).

use crate::Real;

/// The FE Jacobi state on a periodic n^dims grid: the components (φ, E_x, E_y(, E_z)).
#[derive(Debug, Clone, PartialEq)]
pub struct FeJacobi<T> {
    dims: usize,
    n: usize,
    /// Kt∆.
    kt_dl: f64,
    /// `dims + 1` fields of n^dims values, x fastest.
    pub x: Vec<Vec<T>>,
}

const M: [f64; 3] = [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0];
const D: [f64; 3] = [-0.5, 0.0, 0.5];

impl<T: Real> FeJacobi<T> {
    /// A state with every component set by `init(component, voxel index)`; `dims` is 2 or 3.
    pub fn new(dims: usize, n: usize, kt_dl: f64, init: impl Fn(usize, usize) -> f64) -> Self {
        let dims = dims.clamp(2, 3);
        let len = n.pow(dims as u32);
        Self {
            dims,
            n,
            kt_dl,
            x: (0..=dims)
                .map(|c| (0..len).map(|i| T::c(init(c, i))).collect())
                .collect(),
        }
    }

    /// δ₀, the centre of the mass tensor.
    pub fn delta0(&self) -> f64 {
        M[1].powi(self.dims as i32)
    }

    /// One Jacobi iteration of thesis Eq 3.22 without a source.
    #[allow(clippy::needless_range_loop)] // components and voxels index several arrays
    pub fn iterate(&mut self) {
        let (dims, n) = (self.dims, self.n);
        let len = n.pow(dims as u32);
        let offsets: Vec<[usize; 3]> = (0..3usize.pow(dims as u32))
            .map(|t| [t % 3, (t / 3) % 3, if dims == 3 { t / 9 } else { 1 }])
            .collect();
        let d0 = self.delta0();
        let c_mass = T::c(1.0 / d0);
        let c_tr = T::c(27.0 / (24.0 * self.kt_dl));
        let mut out = vec![vec![T::zero(); len]; dims + 1];
        for idx in 0..len {
            let p = [
                idx % n,
                (idx / n) % n,
                if dims == 3 { idx / (n * n) } else { 0 },
            ];
            let mut mass = vec![T::zero(); dims + 1];
            let mut tr = vec![T::zero(); dims + 1];
            for off in &offsets {
                let q: Vec<usize> = (0..dims).map(|a| (p[a] + n + off[a] - 1) % n).collect();
                let qi = q[0] + n * (q[1] + if dims == 3 { n * q[2] } else { 0 });
                let w_mass: f64 = (0..dims).map(|a| M[off[a]]).product();
                let is_centre = (0..dims).all(|a| off[a] == 1);
                if !is_centre {
                    for c in 0..=dims {
                        mass[c] = mass[c] + T::c(w_mass) * self.x[c][qi];
                    }
                }
                for a in 0..dims {
                    let w: f64 = (0..dims)
                        .map(|b| if b == a { D[off[b]] } else { M[off[b]] })
                        .product();
                    let w = T::c(w);
                    tr[0] = tr[0] + T::c(3.0) * w * self.x[1 + a][qi];
                    tr[1 + a] = tr[1 + a] + w * self.x[0][qi];
                }
            }
            for c in 0..=dims {
                out[c][idx] = -(c_tr * tr[c]) - c_mass * mass[c];
            }
        }
        self.x = out;
    }
}
