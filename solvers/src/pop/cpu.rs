//! The CPU propagation of one ordinate (POP Eqs 1–8, spec §1.5–1.7): rayon over the slices
//! along d, generic over `f32`/`f64`, deterministic for any thread count (every cell is a
//! pure gather; every sum is taken per slice and then added in slice order).

use super::grid::{MipLevel, PropagationGrid, dot};
use super::kernel::{Fractions, decay, fractions, hg_view};
use super::{Eq8, Init, Lateral, Observer, Ordinate, PopConfig};
use crate::Real;
use crate::method::Stop;
use rayon::prelude::*;

/// Slots per cell and channel of the state: L, a.
pub(super) const S: usize = 2;
/// Slots per cell and channel of the links: T along +t₁, +t₂, +d, γ along the same, and the
/// ghost transmittance e^{−σa Δx/2} to a vacuum cell beyond an open face.
pub(super) const K: usize = 7;
/// Slots per cell and channel of the accumulators: φ = Σ L^m, J = Σ L^m a^m, L_acc (Eq 8).
pub const ACC: usize = 3;

/// The weight of the step-0 visit of an emission packet in its own cell's accumulators
/// ([`CpuPop::emit`]): ½, so that φ at a cell centre counts the half of the cell's own
/// emission that lies upstream of the centre (as D1's half cell does for a beam). Measured
/// against the exact uncollided fluence in `pop/tests.rs` (`emission_…`); a full visit
/// over-counts by j·Σ_n w_n Δx_n/2.
pub const EMISSION_VISIT: f64 = 0.5;

/// Where the power of one channel has gone, in units of power (L·Δx²), since injection.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Ledger {
    /// Injected into the grid (entry slice: E·n²Δx²; per-cell init: Σ L⁰Δx², see
    /// [`Init::PaperPerCell`]).
    pub injected: f64,
    /// Absorbed (by the transmittances T and by the half cell before the entry centres).
    pub absorbed: f64,
    /// Left through the entry face (k = 0, against d): reflection.
    pub exit_back: f64,
    /// Left through the far face (k = n−1, along d): transmission.
    pub exit_front: f64,
    /// Left through the four lateral faces (open lateral boundary only).
    pub exit_side: f64,
    /// Still in flight: Σ L^m Δx².
    pub in_flight: f64,
}

impl Ledger {
    /// injected − absorbed − exits − in flight (0 up to rounding: spec T3).
    pub fn imbalance(&self) -> f64 {
        self.injected
            - self.absorbed
            - self.exit_back
            - self.exit_front
            - self.exit_side
            - self.in_flight
    }

    /// All light that has left the grid.
    pub fn exited(&self) -> f64 {
        self.exit_back + self.exit_front + self.exit_side
    }
}

/// A view of a [`CpuPop`] for the GPU upload (see [`CpuPop::parts`]).
pub(super) struct Parts<'a, T> {
    /// `[cell][channel][L, a]`.
    pub state: &'a [T],
    /// `[cell][channel][K]`.
    pub links: &'a [T],
    /// `[cell][channel][φ, J, L_acc]`.
    pub acc: &'a [T],
    /// Per cell u of Eq 8, when an observer is set.
    pub view_u: Option<&'a [T]>,
    /// Per channel: the factor Eq 8 multiplies a by.
    pub lobe: Vec<f64>,
    /// The lateral faces.
    pub lateral: Lateral,
    /// Per channel, the power so far.
    pub ledger: &'a [Ledger],
    /// Steps run so far.
    pub steps: usize,
}

/// The propagation state of one ordinate on one [`PropagationGrid`].
#[derive(Debug, Clone)]
pub struct CpuPop<T> {
    grid: PropagationGrid,
    nc: usize,
    lateral: Lateral,
    eq8: Eq8,
    /// [cell][channel][L, a], current and next.
    state: Vec<T>,
    next: Vec<T>,
    /// [cell][channel][front, side, back] of the current state.
    frac: Vec<T>,
    /// [cell][channel][K].
    links: Vec<T>,
    /// [cell][channel][φ, J, L_acc].
    acc: Vec<T>,
    /// Per cell: u = d·(direction to the observer) (Eq 8), when an observer is set.
    view_u: Option<Vec<T>>,
    /// Per channel: g, and the factor Eq 8 multiplies a by (g for PhaseConvolved, 1 for
    /// Literal).
    g: Vec<f64>,
    ledger: Vec<Ledger>,
    /// Per step: max over channels of the in-flight power / injected.
    history: Vec<f64>,
    steps: usize,
    /// Medium samples per cell and channel: (σs, σa).
    sigma: Vec<(f64, f64)>,
}

impl<T: Real> CpuPop<T> {
    /// A grid with the medium `mip` resampled at its cell centres and channel phase
    /// parameters `g`, empty (nothing injected).
    pub fn new(grid: PropagationGrid, mip: &MipLevel, g: &[f64], config: &PopConfig) -> Self {
        let nc = g.len();
        let n = grid.n;
        let len = grid.len();
        let mut sigma = vec![(0.0, 0.0); len * nc];
        sigma
            .par_chunks_mut(n * n * nc)
            .enumerate()
            .for_each(|(k, slice)| {
                for j in 0..n {
                    for i in 0..n {
                        let p = grid.center(i, j, k);
                        for ch in 0..nc {
                            slice[(i + n * j) * nc + ch] = mip.sample(ch, p);
                        }
                    }
                }
            });
        Self::with_samples(grid, sigma, g, config)
    }

    /// A grid whose cells hold the given (σs, σa) per cell and channel (`[cell][channel]`),
    /// for tests that set the medium in grid space (laterally periodic slabs).
    pub fn with_samples(
        grid: PropagationGrid,
        sigma: Vec<(f64, f64)>,
        g: &[f64],
        config: &PopConfig,
    ) -> Self {
        let nc = g.len();
        let n = grid.n;
        let len = grid.len();
        let dx = grid.dx;
        let lateral = config.lateral;
        let mut links = vec![T::zero(); len * nc * K];
        links
            .par_chunks_mut(n * n * nc * K)
            .enumerate()
            .for_each(|(k, slice)| {
                for j in 0..n {
                    for i in 0..n {
                        let cell = i + n * (j + n * k);
                        let nb = [
                            neighbour_plus(i, n, lateral).map(|ii| ii + n * (j + n * k)),
                            neighbour_plus(j, n, lateral).map(|jj| i + n * (jj + n * k)),
                            (k + 1 < n).then(|| i + n * (j + n * (k + 1))),
                        ];
                        for ch in 0..nc {
                            let (ss, sa) = sigma[cell * nc + ch];
                            let out = &mut slice[((i + n * j) * nc + ch) * K..][..K];
                            for (axis, other) in nb.iter().enumerate() {
                                // A missing neighbour is a vacuum ghost cell: the means
                                // are half the cell's own σ.
                                let (os, oa) = other.map_or((0.0, 0.0), |o| sigma[o * nc + ch]);
                                let mean_a = 0.5 * (sa + oa);
                                let mean_s = 0.5 * (ss + os);
                                out[axis] = T::c((-mean_a * dx).exp());
                                out[3 + axis] = T::c(decay(g[ch], mean_s * dx));
                            }
                            out[6] = T::c((-0.5 * sa * dx).exp());
                        }
                    }
                }
            });
        let view_u = config.observer.map(|obs| {
            let d = grid.axes[2];
            let mut u = vec![T::zero(); len];
            u.par_chunks_mut(n * n).enumerate().for_each(|(k, slice)| {
                for j in 0..n {
                    for i in 0..n {
                        let w = match obs {
                            Observer::Point(c) => {
                                let x = grid.center(i, j, k);
                                let r = [c[0] - x[0], c[1] - x[1], c[2] - x[2]];
                                let l = dot(r, r).sqrt();
                                if l > 0.0 { r.map(|v| v / l) } else { d }
                            }
                            Observer::Direction(w) => w,
                        };
                        slice[i + n * j] = T::c(dot(d, w));
                    }
                }
            });
            u
        });
        Self {
            grid,
            nc,
            lateral,
            eq8: config.eq8,
            state: vec![T::zero(); len * nc * S],
            next: vec![T::zero(); len * nc * S],
            frac: vec![T::zero(); len * nc * 3],
            links,
            acc: vec![T::zero(); len * nc * ACC],
            view_u,
            g: g.to_vec(),
            ledger: vec![Ledger::default(); nc],
            history: Vec::new(),
            steps: 0,
            sigma,
        }
    }

    /// The grid.
    pub fn grid(&self) -> &PropagationGrid {
        &self.grid
    }

    /// Channels.
    pub fn channels(&self) -> usize {
        self.nc
    }

    /// Steps run.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Per channel, where the power has gone.
    pub fn ledger(&self) -> &[Ledger] {
        &self.ledger
    }

    /// Per step m = 1…: max over channels of R^m/P_injected (spec D9).
    pub fn history(&self) -> &[f64] {
        &self.history
    }

    /// The accumulators `[cell][channel][φ, J, L_acc]` (see [`ACC`]).
    pub fn accumulators(&self) -> &[T] {
        &self.acc
    }

    /// The current (L, a) of cell `cell`, channel `ch`.
    pub fn cell(&self, cell: usize, ch: usize) -> (T, T) {
        let s = (cell * self.nc + ch) * S;
        (self.state[s], self.state[s + 1])
    }

    /// Fluence φ = Σ_m L^m of cell `cell`, channel `ch` (spec D5).
    pub fn phi(&self, cell: usize, ch: usize) -> T {
        self.acc[(cell * self.nc + ch) * ACC]
    }

    /// Injects one ordinate (spec §1.5): [`Init::EntrySlice`] (D1) or the paper's
    /// [`Init::PaperPerCell`]. Adds to whatever is in the grid.
    pub fn inject(&mut self, ordinate: &Ordinate, init: Init) {
        let n = self.grid.n;
        let nc = self.nc;
        let dx = self.grid.dx;
        let area = dx * dx;
        let e = ordinate.irradiance;
        for ch in 0..nc {
            let g = self.g[ch];
            for j in 0..n {
                for i in 0..n {
                    let mut tau = 0.0;
                    let kmax = match init {
                        Init::EntrySlice => 1,
                        Init::PaperPerCell => n,
                    };
                    for k in 0..kmax {
                        let cell = i + n * (j + n * k);
                        let (ss, sa) = self.sigma[cell * nc + ch];
                        let (l, a) = match init {
                            Init::EntrySlice => {
                                let l = e * (-0.5 * sa * dx).exp();
                                self.ledger[ch].injected += e * area;
                                self.ledger[ch].absorbed += (e - l) * area;
                                (l, ordinate.anisotropy * decay(g, 0.5 * ss * dx))
                            }
                            Init::PaperPerCell => {
                                let l = e * (-(tau + 0.5 * (ss + sa) * dx)).exp();
                                tau += (ss + sa) * dx;
                                self.ledger[ch].injected += l * area;
                                (l, ordinate.anisotropy)
                            }
                        };
                        self.add_cell(cell, ch, l, a);
                    }
                }
            }
        }
    }

    /// Injects the volume emission (ours, not the paper's; module docs, "Volume emission"):
    /// every cell and channel receives at step 0 the power j·Δx³·`share` (`j` per
    /// `[cell][channel]`, from [`super::grid::resample_emission`]), i.e. L = j·`share`·Δx,
    /// with anisotropy `a` along d, counted as injected and in flight like any packet
    /// ([`CpuPop::add_cell`]). Its own cell sees it with visit weight ½ ([`EMISSION_VISIT`]):
    /// the packet stands for light emitted uniformly through the cell, and φ is a point
    /// value at the centre, where half of that light has arrived. Adds to whatever is in
    /// the grid; the steps then run the Neumann series Σ_m P^m S of the step-0 source.
    pub fn emit(&mut self, j: &[f64], share: f64, a: f64) {
        let dx = self.grid.dx;
        for cell in 0..self.grid.len() {
            for ch in 0..self.nc {
                let l = j[cell * self.nc + ch] * share * dx;
                if l > 0.0 {
                    self.ledger[ch].injected += l * dx * dx;
                    self.add_packet(cell, ch, l, a, EMISSION_VISIT);
                }
            }
        }
    }

    /// Adds a packet of radiance `l` and anisotropy `a` to cell `cell`, channel `ch` (its
    /// anisotropy becomes the L-weighted mean, Eq 6), counted as injected and accumulated
    /// as a visit (φ += l).
    pub fn add_cell(&mut self, cell: usize, ch: usize, l: f64, a: f64) {
        self.add_packet(cell, ch, l, a, 1.0);
    }

    /// [`CpuPop::add_cell`] with the accumulators (φ, J, L_acc) taking `visit`·l.
    fn add_packet(&mut self, cell: usize, ch: usize, l: f64, a: f64, visit: f64) {
        let s = (cell * self.nc + ch) * S;
        let (l0, a0) = (self.state[s].f(), self.state[s + 1].f());
        let lt = l0 + l;
        self.state[s] = T::c(lt);
        self.state[s + 1] = T::c(if lt > 0.0 {
            (l0 * a0 + l * a) / lt
        } else {
            0.0
        });
        let area = self.grid.dx * self.grid.dx;
        self.ledger[ch].in_flight += l * area;
        let acc = (cell * self.nc + ch) * ACC;
        let lv = T::c(l * visit);
        let av = T::c(a);
        self.acc[acc] = self.acc[acc] + lv;
        self.acc[acc + 1] = self.acc[acc + 1] + lv * av;
        if let Some(u) = &self.view_u {
            let lobe = av * T::c(self.lobe_factor(ch));
            self.acc[acc + 2] = self.acc[acc + 2] + lv * hg_view(u[cell], lobe);
        }
    }

    /// What the GPU kernel uploads (`pop/gpu.rs`): the state, the links, the accumulators,
    /// the per-cell u of Eq 8, the Eq 8 lobe factor per channel, the lateral faces and the
    /// ledger so far.
    pub(super) fn parts(&self) -> Parts<'_, T> {
        Parts {
            state: &self.state,
            links: &self.links,
            acc: &self.acc,
            view_u: self.view_u.as_deref(),
            lobe: (0..self.nc).map(|ch| self.lobe_factor(ch)).collect(),
            lateral: self.lateral,
            ledger: &self.ledger,
            steps: self.steps,
        }
    }

    /// Counts a packet added by [`CpuPop::add_cell`] as injected (tests that place packets).
    pub fn count_injected(&mut self, ch: usize, power: f64) {
        self.ledger[ch].injected += power;
    }

    fn lobe_factor(&self, ch: usize) -> f64 {
        match self.eq8 {
            Eq8::PhaseConvolved => self.g[ch],
            Eq8::Literal => 1.0,
        }
    }

    /// One iteration m → m+1: Eq 3 fractions of every cell, then the 6-neighbour gather of
    /// Eqs 2, 4–6 into the other buffer, the accumulation of Eqs 7–8 and the ledger.
    pub fn step(&mut self) {
        let n = self.grid.n;
        let nc = self.nc;
        let plane = n * n;
        let lateral = self.lateral;
        // Pass 1: fractions and where the light leaving each cell goes (absorbed, exits).
        let state = &self.state;
        let links = &self.links;
        let losses: Vec<Vec<[f64; 4]>> = self
            .frac
            .par_chunks_mut(plane * nc * 3)
            .enumerate()
            .map(|(k, fr)| {
                let mut sums = vec![[0.0f64; 4]; nc];
                for j in 0..n {
                    for i in 0..n {
                        let cell = i + n * (j + n * k);
                        for ch in 0..nc {
                            let slot = cell * nc + ch;
                            let l = state[slot * S].f();
                            if l == 0.0 {
                                // Nothing to send: the gather multiplies the (stale, finite)
                                // fractions by L = 0.
                                continue;
                            }
                            let a = state[slot * S + 1];
                            let f: Fractions<T> = fractions(a);
                            let o = ((i + n * j) * nc + ch) * 3;
                            fr[o] = f.front;
                            fr[o + 1] = f.side;
                            fr[o + 2] = f.back;
                            let (front, side, back) = (f.front.f(), f.side.f(), f.back.f());
                            let lk = &links[slot * K..][..K];
                            let ghost = lk[6].f();
                            let s = &mut sums[ch];
                            let mut go = |frac: f64, t: Option<f64>, exit: usize| match t {
                                Some(t) => s[0] += l * frac * (1.0 - t),
                                None => {
                                    s[0] += l * frac * (1.0 - ghost);
                                    s[exit] += l * frac * ghost;
                                }
                            };
                            // Along d.
                            go(front, (k + 1 < n).then(|| lk[2].f()), 2);
                            let below = (k > 0).then(|| links[(slot - plane * nc) * K + 2].f());
                            go(back, below, 1);
                            // Lateral.
                            let open = lateral == Lateral::Open;
                            let ip = !(open && i + 1 == n);
                            go(side, ip.then(|| lk[0].f()), 3);
                            let jp = !(open && j + 1 == n);
                            go(side, jp.then(|| lk[1].f()), 3);
                            let im = neighbour_minus(i, n, lateral)
                                .map(|ii| links[((ii + n * (j + n * k)) * nc + ch) * K].f());
                            go(side, im, 3);
                            let jm = neighbour_minus(j, n, lateral)
                                .map(|jj| links[((i + n * (jj + n * k)) * nc + ch) * K + 1].f());
                            go(side, jm, 3);
                        }
                    }
                }
                sums
            })
            .collect();
        // Pass 2: the gather.
        let frac = &self.frac;
        let view_u = self.view_u.as_deref();
        let lobe: Vec<T> = (0..nc).map(|ch| T::c(self.lobe_factor(ch))).collect();
        let lobe = &lobe;
        let flight: Vec<Vec<f64>> = self
            .next
            .par_chunks_mut(plane * nc * S)
            .zip(self.acc.par_chunks_mut(plane * nc * ACC))
            .enumerate()
            .map(|(k, (out, acc))| {
                let mut sums = vec![0.0f64; nc];
                for j in 0..n {
                    for i in 0..n {
                        let cell = i + n * (j + n * k);
                        // Sources: (cell, which fraction 0/1/2, link slot (cell, axis)).
                        let mut src: [(usize, usize, usize, usize); 6] = [(0, 0, 0, 0); 6];
                        let mut ns = 0;
                        if k > 0 {
                            let s = cell - plane;
                            src[ns] = (s, 0, s, 2);
                            ns += 1;
                        }
                        if k + 1 < n {
                            src[ns] = (cell + plane, 2, cell, 2);
                            ns += 1;
                        }
                        if let Some(ii) = neighbour_minus(i, n, lateral) {
                            let s = ii + n * (j + n * k);
                            src[ns] = (s, 1, s, 0);
                            ns += 1;
                        }
                        if let Some(ii) = neighbour_plus(i, n, lateral) {
                            src[ns] = (ii + n * (j + n * k), 1, cell, 0);
                            ns += 1;
                        }
                        if let Some(jj) = neighbour_minus(j, n, lateral) {
                            let s = i + n * (jj + n * k);
                            src[ns] = (s, 1, s, 1);
                            ns += 1;
                        }
                        if let Some(jj) = neighbour_plus(j, n, lateral) {
                            src[ns] = (i + n * (jj + n * k), 1, cell, 1);
                            ns += 1;
                        }
                        for ch in 0..nc {
                            let mut sum = T::zero();
                            let mut wa = T::zero();
                            for &(s, which, lc, axis) in &src[..ns] {
                                let ss = s * nc + ch;
                                let l = state[ss * S];
                                let link = (lc * nc + ch) * K;
                                let dl = l * frac[ss * 3 + which] * links[link + axis];
                                sum = sum + dl;
                                wa = wa + dl * state[ss * S + 1] * links[link + 3 + axis];
                            }
                            let a = if sum > T::zero() {
                                (wa / sum).max(T::zero()).min(T::one())
                            } else {
                                T::zero()
                            };
                            let o = ((i + n * j) * nc + ch) * S;
                            out[o] = sum;
                            out[o + 1] = a;
                            let q = ((i + n * j) * nc + ch) * ACC;
                            acc[q] = acc[q] + sum;
                            acc[q + 1] = acc[q + 1] + sum * a;
                            if let Some(u) = view_u {
                                acc[q + 2] = acc[q + 2] + sum * hg_view(u[cell], a * lobe[ch]);
                            }
                            sums[ch] += sum.f();
                        }
                    }
                }
                sums
            })
            .collect();
        std::mem::swap(&mut self.state, &mut self.next);
        let area = self.grid.dx * self.grid.dx;
        let mut worst = 0f64;
        for ch in 0..nc {
            let led = &mut self.ledger[ch];
            for slice in &losses {
                led.absorbed += slice[ch][0] * area;
                led.exit_back += slice[ch][1] * area;
                led.exit_front += slice[ch][2] * area;
                led.exit_side += slice[ch][3] * area;
            }
            led.in_flight = flight.iter().map(|s| s[ch]).sum::<f64>() * area;
            worst = worse_residual(worst, led.in_flight, led.injected);
        }
        self.history.push(worst);
        self.steps += 1;
    }

    /// Steps until the relative residual power R^m/P_inj of every channel is below
    /// `tolerance` (spec D9; 0: never) or `max_iterations` steps have run in total.
    pub fn run(&mut self, tolerance: f64, max_iterations: usize) -> Stop {
        loop {
            if let Some(&r) = self.history.last() {
                if !r.is_finite() {
                    return Stop::NonFinite;
                }
                if r < tolerance || r == 0.0 {
                    return Stop::Converged;
                }
            }
            if self.steps >= max_iterations {
                return Stop::Cap;
            }
            self.step();
        }
    }
}

/// The running D9 residual over channels: the larger of `worst` and in flight/injected
/// (0 when nothing was injected); NaN once any channel is not finite.
#[inline]
pub(crate) fn worse_residual(worst: f64, in_flight: f64, injected: f64) -> f64 {
    let r = if injected > 0.0 {
        in_flight / injected
    } else {
        0.0
    };
    if r.is_finite() {
        worst.max(r)
    } else {
        f64::NAN
    }
}

/// The +1 neighbour of index `i` along a lateral axis of `n` cells, if any.
#[inline(always)]
fn neighbour_plus(i: usize, n: usize, lateral: Lateral) -> Option<usize> {
    if i + 1 < n {
        Some(i + 1)
    } else if lateral == Lateral::Periodic && n > 1 {
        Some(0)
    } else {
        None
    }
}

/// The −1 neighbour of index `i` along a lateral axis of `n` cells, if any.
#[inline(always)]
fn neighbour_minus(i: usize, n: usize, lateral: Lateral) -> Option<usize> {
    if i > 0 {
        Some(i - 1)
    } else if lateral == Lateral::Periodic && n > 1 {
        Some(n - 1)
    } else {
        None
    }
}
