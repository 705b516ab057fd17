//! LPM Alg 1 (Fattal's sequential form): one thread, no T buffer. Every ray's sub-segment
//! deposits its scattered light straight into U^{cur}, I and φ^p, in the paper's loop order
//! "for each LPM → for each propagation direction i → for each element (r, s) → for each
//! intersected voxel t" (spec §1.5). On a GPU these scattered writes race (Fig 3); that is
//! what Gruson's propagate/collect split (Alg 2, [`super::CpuLpm`]) removes. Here it is the
//! "Fattal original" baseline of the Fig 8 speed-up experiment (`experiments::lpm_speedup`)
//! and the reference of test T15.
//!
//! **Same numbers, different summation.** The sub-segment update is the public
//! `cpu::segment` (LPM Eq 3 in the conservative form, spec §1.6) on the shared geometry
//! tables ([`DirectionTable`]), directions and phase matrix, with the same wrap rules (D12),
//! formulas (D3–D6), stopping rules (D1) and tallies. Per sub-segment of direction i in voxel
//! v with ∫L ds = `int`, Alg 1 adds σs_v·A_i F^{i,d′}/(h³|Ω^{d′}|)·int to every U^{d′,cur}_v
//! (and to I: the cone average for one I, per cone for six) and A_i|Ω^i|/h³·int to φ^p_v at
//! once; Alg 2 first sums ∫L ds per (i, v) into T^i and adds the weighted sum over the
//! face's directions once per voxel. The two differ only by the order of the additions. The
//! paper's deposit (D3) deposits L_in(1 − e^{−σs s}) instead of σs∫L ds, as Alg 2 does.
//!
//! The order's tallies are formed as Alg 2 forms them, from the same quantities: injected
//! and exited ray sums weighted by A|Ω^i| per direction, emitted Σ_i A|Ω^i|·h·(path factor)/
//! |ω_n|·Σ_v U_v, scattered Σ_v Σ_d′ ΔU^{d′}|Ω^{d′}|h³ (read from U^{cur} after the order,
//! which starts at zero) and absorbed Σ_v σa φ^p h³ (so the inner loop carries no f64
//! tallies).
//!
//! **T15 measured** (`alg1::tests`, 9×11×8 white-noise medium: 20 % vacuum, σt·h to 3,
//! albedo in [0, 1], emission in 5 % of the voxels; environment of radiance 1 plus a
//! directional light of irradiance 2 along (0.3, −0.2, 0.9); 3 orders; over every field I,
//! U, φ and the kept φ^p: the largest relative difference where the reference exceeds 10⁻⁶
//! of its maximum / the largest relative RMSE of a field):
//!
//! | case | f64 Alg 1 vs Alg 2 | f32 Alg 1 vs Alg 2 | f32 vs f64: Alg 1 | Alg 2 |
//! |---|---|---|---|---|
//! | open wrap, m = 5 | 6.8·10⁻¹⁵ / 1.9·10⁻¹⁵ | 3.0·10⁻⁶ / 8.1·10⁻⁷ | 8.4·10⁻⁷ | 1.5·10⁻⁷ |
//! | zero wrap, m = 3 | 4.0·10⁻¹⁵ / 8.1·10⁻¹⁶ | 1.7·10⁻⁶ / 4.9·10⁻⁷ | 5.0·10⁻⁷ | 1.6·10⁻⁷ |
//! | periodic wrap, m = 4 | 3.3·10⁻¹⁵ / 1.2·10⁻¹⁵ | 2.4·10⁻⁶ / 5.0·10⁻⁷ | 4.8·10⁻⁷ | 1.5·10⁻⁷ |
//! | paper formulas, m = 3 | 2.1·10⁻¹⁵ / 5.4·10⁻¹⁶ | 1.2·10⁻⁶ / 3.2·10⁻⁷ | 3.1·10⁻⁷ | 9.4·10⁻⁸ |
//! | HG g = 0.7, six I, m = 3 | 2.8·10⁻¹⁵ / 7.7·10⁻¹⁶ | 1.8·10⁻⁶ / 3.9·10⁻⁷ | 3.9·10⁻⁷ | 1.5·10⁻⁷ |
//!
//! (the last two columns: relative RMSE against the f64 Alg 2). The relative stopping rule
//! (rel 10⁻⁴, m = 3, 7×6×8) stops both after 20 orders with fields 1.1·10⁻¹⁴ apart
//! (`t15_alg1_stops_like_alg2`). Tallies agree to 1.2·10⁻¹⁵ (f64) and 4.6·10⁻⁸ (f32) of
//! the input. Bounds: the spec's 10⁻¹³ in f64; in f32 the spec's 10⁻⁶ holds as the relative
//! RMSE, not voxel by voxel: single voxels differ by up to 3.0·10⁻⁶ (bound 10⁻⁵, T18's pair
//! of bounds). That is Alg 1's own f32 rounding, 5× Alg 2's: a voxel receives each of its
//! ~294 sub-segment deposits per order as a separate rounded f32 addition to U, I and φ,
//! where Alg 2 adds one sum per direction to T and one per voxel and face to U.
//!
//! **GPU slotted ≡ Alg 1** (`t15_gpu_slotted_equals_alg1`, lavapipe llvmpipe Mesa 22.3.6,
//! f32, the same medium and lights, 3 orders): open wrap m = 5 3.0·10⁻⁶ / 8.2·10⁻⁷, HG
//! g = 0.7 with six I, m = 3 1.8·10⁻⁶ / 3.9·10⁻⁷; tallies 2.8·10⁻⁷ (bounds as for f32 above).

use super::cpu::{segment, series_threshold};
use super::directions::{CONE_SOLID_ANGLE, CONES, Directions, PhaseMatrix, lateral_axes};
use super::geometry::DirectionTable;
use super::{
    BoundaryLight, Deposit, LpmConfig, LpmSolution, Memory, MemoryBytes, OrderTally, WrapBc,
};
use crate::{Grid, Medium, Real, SolverError};
use std::f64::consts::PI;

/// A prepared Alg 1 solve on one medium: directions, phase matrix, geometry tables and the
/// medium in the working precision (no T buffers, no threads).
#[derive(Debug, Clone)]
pub struct Alg1Lpm<T> {
    /// The grid.
    pub grid: Grid,
    /// The settings.
    pub config: LpmConfig,
    /// The propagation directions.
    pub dirs: Directions,
    /// F of LPM Eq 5.
    pub phase: PhaseMatrix,
    /// One sub-segment table per direction (its face's sweep length).
    pub tables: Vec<DirectionTable>,
    sigma_t: Vec<T>,
    sigma_s: Vec<T>,
    /// U⁰ = I⁰ = j/4π per voxel (D9).
    source: Vec<T>,
}

/// Our per-buffer byte count of an Alg 1 solve: Alg 2's ([`super::memory_bytes`]) without
/// the T buffers, the x-layout copies of σt and σs and the transient scratch; one ray state.
pub fn alg1_memory_bytes(grid: &Grid, config: &LpmConfig, word: u64) -> MemoryBytes {
    let full = super::memory_bytes(grid, config, word);
    let nv = grid.len() as u64;
    MemoryBytes {
        medium: (3 * nv).saturating_mul(word),
        t: 0,
        rays: word,
        ..full
    }
}

impl<T: Real> Alg1Lpm<T> {
    /// Prepares a solve; validates the medium and the settings and refuses a grid whose
    /// buffers exceed the memory budget (before allocating them).
    pub fn new(medium: &Medium<T>, config: &LpmConfig) -> Result<Self, SolverError> {
        config.validate()?;
        medium.validate()?;
        let grid = medium.grid;
        let dirs = Directions::new(config.m)?;
        let bytes = alg1_memory_bytes(&grid, config, std::mem::size_of::<T>() as u64);
        config.check_budget(&grid, bytes.total())?;
        let phase = PhaseMatrix::new(&dirs, config.phase, config.quadrature)?;
        let tables = dirs
            .dirs
            .iter()
            .map(|d| DirectionTable::new(d, config.m, grid.n[d.face / 2]))
            .collect();
        let four_pi = T::c(4.0 * PI);
        Ok(Self {
            grid,
            config: config.clone(),
            sigma_s: medium
                .sigma_t
                .iter()
                .zip(&medium.albedo)
                .map(|(&s, &a)| s * a)
                .collect(),
            sigma_t: medium.sigma_t.clone(),
            source: medium.emission.iter().map(|&j| j / four_pi).collect(),
            dirs,
            phase,
            tables,
        })
    }

    /// Sub-segments one order processes (the same count as Alg 2's).
    pub fn sub_segments_per_order(&self) -> u64 {
        self.dirs
            .dirs
            .iter()
            .zip(&self.tables)
            .map(|(d, t)| super::sweep_segments(&self.grid, d, t))
            .sum()
    }

    /// A of direction i: A⊥ = h²|ω·n_f| (D6) or the face area h².
    fn area(&self, i: usize) -> f64 {
        let cos = self.dirs.dirs[i].cos_axis;
        self.config.formulas.area(self.grid.dl, cos)
    }

    /// The factor on the Euclidean length: 1 (D5) or the paper's 1/|ω_n|.
    fn path_factor(&self, i: usize) -> f64 {
        self.config.formulas.path_factor(self.dirs.dirs[i].cos_axis)
    }

    /// Marches every ray of direction `i` (element by element, voxel by voxel), depositing
    /// into `out` at once. Returns the (injected, exited) ray sums.
    fn march(
        &self,
        i: usize,
        u_src: &[T],
        l_bc: f64,
        order: usize,
        out: &mut Out<'_, T>,
    ) -> (f64, f64) {
        let dir = &self.dirs.dirs[i];
        let (a, sign) = dir.axis();
        let (b, c) = lateral_axes(a);
        let n = self.grid.n;
        let (na, nb, nc) = (n[a], n[b], n[c]);
        let stride = [1, n[0], n[0] * n[1]];
        let (sa, sb, sc) = (stride[a], stride[b], stride[c]);
        let (wphi, wu) = super::collect_weights(
            &self.grid,
            &self.config.formulas,
            &self.dirs,
            &self.phase,
            i,
        );
        let (wphi, wu) = (T::c(wphi), wu.map(T::c));
        let scale = self.grid.dl * self.path_factor(i);
        let l0 = if order == 0 { l_bc } else { 0.0 };
        let reentry = match self.config.wrap {
            WrapBc::Zero => Some(T::zero()),
            WrapBc::Open => Some(T::c(l0)),
            WrapBc::Periodic => None,
        };
        let paper = self.config.formulas.deposit == Deposit::Paper;
        let ts = series_threshold::<T>();
        let sixth = T::c(1.0 / 6.0);
        let table = &self.tables[i];
        let (mut injected, mut exited) = (0.0, 0.0);
        for rc in 0..nc {
            for rb in 0..nb {
                let mut l = T::c(l0);
                injected += l0;
                let mut prev = [0i64; 2];
                for z in 0..na {
                    let slab = if sign > 0 { z } else { na - 1 - z };
                    for seg in table.slab(z) {
                        let [ob, oc] = seg.offset;
                        let xb = rb as i64 + ob;
                        let xc = rc as i64 + oc;
                        if let Some(re) = reentry {
                            // The ray crossed a side face (A) and re-enters at B (Fig 2).
                            let wrapped = xb.div_euclid(nb as i64)
                                != (rb as i64 + prev[0]).div_euclid(nb as i64)
                                || xc.div_euclid(nc as i64)
                                    != (rc as i64 + prev[1]).div_euclid(nc as i64);
                            if wrapped {
                                exited += l.f();
                                l = re;
                                injected += re.f();
                            }
                        }
                        prev = seg.offset;
                        let v = slab * sa
                            + xb.rem_euclid(nb as i64) as usize * sb
                            + xc.rem_euclid(nc as i64) as usize * sc;
                        let len = T::c(seg.len * scale);
                        let ss = self.sigma_s[v];
                        let dep = if paper {
                            -(l * (-(ss * len)).exp_m1())
                        } else {
                            T::zero()
                        };
                        let (l_out, int) = segment(l, u_src[v], self.sigma_t[v], len, ts);
                        l = l_out;
                        let src = if paper { dep } else { ss * int };
                        let mut total = T::zero();
                        for (d, &w) in wu.iter().enumerate() {
                            let du = w * src;
                            out.u_cur[d][v] = out.u_cur[d][v] + du;
                            if out.intensity.len() == CONES {
                                out.intensity[d][v] = out.intensity[d][v] + du;
                            }
                            total = total + du;
                        }
                        if out.intensity.len() == 1 {
                            out.intensity[0][v] = out.intensity[0][v] + total * sixth;
                        }
                        out.phi_p[v] = out.phi_p[v] + wphi * int;
                    }
                }
                exited += l.f();
            }
        }
        (injected, exited)
    }

    /// Marches order 0 of only the directions `dirs` (indices into [`Self::dirs`]) into
    /// scratch buffers and returns (sub-segments processed, seconds): a throughput sample for
    /// grids where a whole sequential order takes too long (the Fig 8 experiment at 128³).
    /// An index out of range is a typed error naming `dirs`.
    pub fn time_directions(
        &self,
        boundary: &BoundaryLight,
        dirs: &[usize],
    ) -> Result<(u64, f64), SolverError> {
        boundary.check(&self.dirs)?;
        if let Some(&i) = dirs.iter().find(|&&i| i >= self.dirs.len()) {
            return Err(SolverError::BadParameter {
                name: "dirs",
                value: i as f64,
                reason: "a direction index beyond the direction set",
            });
        }
        let nv = self.grid.len();
        let mut u_cur: Vec<Vec<T>> = (0..CONES).map(|_| vec![T::zero(); nv]).collect();
        let mut intensity: Vec<Vec<T>> = (0..self.config.storage_i.count())
            .map(|_| vec![T::zero(); nv])
            .collect();
        let mut phi_p = vec![T::zero(); nv];
        let start = std::time::Instant::now();
        let mut segments = 0u64;
        for &i in dirs {
            let d = &self.dirs.dirs[i];
            let mut out = Out {
                u_cur: &mut u_cur,
                intensity: &mut intensity,
                phi_p: &mut phi_p,
            };
            self.march(i, &self.source, boundary.radiance[i], 0, &mut out);
            segments += super::sweep_segments(&self.grid, d, &self.tables[i]);
        }
        Ok((segments, start.elapsed().as_secs_f64()))
    }

    /// Runs the scattering orders (Jacobi by order, as Alg 2, with D1, D2) with the boundary
    /// radiance `boundary`, sequentially. `observer(order, unshot / unshot after order 0)`
    /// sees every order.
    pub fn solve(
        &self,
        boundary: &BoundaryLight,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<LpmSolution<T>, SolverError> {
        boundary.check(&self.dirs)?;
        let start = std::time::Instant::now();
        let nv = self.grid.len();
        let per = self.dirs.per_face();
        let d_i = self.config.storage_i.count();
        let mut orders = super::OrderLoop::new(self.config.orders);
        let mut u_prev: Vec<Vec<T>> = (0..CONES).map(|_| self.source.clone()).collect();
        let mut u_cur: Vec<Vec<T>> = (0..CONES).map(|_| vec![T::zero(); nv]).collect();
        let mut intensity: Vec<Vec<T>> = (0..d_i).map(|_| self.source.clone()).collect();
        let mut phi = vec![T::zero(); nv];
        let mut phi_orders: Vec<Vec<T>> = Vec::new();
        let h3 = self.grid.dl.powi(3);
        for order in 0..orders.max_orders {
            for u in &mut u_cur {
                u.fill(T::zero());
            }
            let mut phi_p = vec![T::zero(); nv];
            let mut tally = OrderTally::default();
            for (face, u_src) in u_prev.iter().enumerate() {
                let sum_u: f64 = u_src.iter().map(|x| x.f()).sum();
                let mut out = Out {
                    u_cur: &mut u_cur,
                    intensity: &mut intensity,
                    phi_p: &mut phi_p,
                };
                for k in 0..per {
                    let i = face * per + k;
                    let (inj, exi) = self.march(i, u_src, boundary.radiance[i], order, &mut out);
                    let dir = &self.dirs.dirs[i];
                    let w = self.area(i) * dir.solid_angle;
                    tally.injected += w * inj;
                    tally.exited += w * exi;
                    tally.emitted += w * self.grid.dl * self.path_factor(i) / dir.cos_axis * sum_u;
                }
            }
            tally.scattered = u_cur
                .iter()
                .map(|u| u.iter().map(|x| x.f()).sum::<f64>())
                .sum::<f64>()
                * CONE_SOLID_ANGLE
                * h3;
            tally.absorbed = (0..nv)
                .map(|v| (self.sigma_t[v] - self.sigma_s[v]).f() * phi_p[v].f())
                .sum::<f64>()
                * h3;
            std::mem::swap(&mut u_prev, &mut u_cur);
            for (t, p) in phi.iter_mut().zip(&phi_p) {
                *t = *t + *p;
            }
            if self.config.keep_orders {
                phi_orders.push(phi_p);
            }
            if orders.finish(order, tally, &mut observer) {
                break;
            }
        }
        let word = std::mem::size_of::<T>();
        let allocated = (u_prev.len() + u_cur.len() + intensity.len() + 4 + phi_orders.len()) * nv;
        Ok(LpmSolution {
            grid: self.grid,
            intensity,
            unshot: u_prev,
            phi,
            phi_orders,
            orders: orders.tallies.len(),
            tallies: orders.tallies,
            stop: orders.stop,
            seconds: start.elapsed().as_secs_f64(),
            memory: Memory {
                formula: alg1_memory_bytes(&self.grid, &self.config, word as u64),
                resident_measured: (allocated * word) as u64 + super::table_bytes(&self.tables),
                // No T buffer, nothing to slice: one slice of the whole grid.
                slabs: self.grid.n.iter().copied().max().unwrap_or(1),
            },
        })
    }
}

/// The buffers a march deposits into.
struct Out<'a, T> {
    u_cur: &'a mut [Vec<T>],
    intensity: &'a mut [Vec<T>],
    phi_p: &'a mut [T],
}

#[cfg(test)]
mod tests;
