use solvers::fld::*;
use solvers::scenes;
use std::time::Instant;
fn run<T: solvers::Real>(n: usize, lim: FluxLimiter) {
    let m = scenes::vacuum_cloud::<T>(n, 1).unwrap();
    let eps: f64 = if T::NAME == "f32" { 1e-10 } else { 1e-20 }; let cfg = FldConfig { limiter: lim, epsilon: Some(eps), ..FldConfig::default() };
    let mut s = CpuFld::new(&m, &Boundary::Zero, &cfg).unwrap();
    for _ in 0..3 { s.iterate(); }
    let t = Instant::now(); let it = 20;
    for _ in 0..it { s.iterate(); }
    let dt = t.elapsed().as_secs_f64() / it as f64;
    println!("{} {} n={n}: {:.2} ms/iter, {:.0} Mvox/s, {:.2} GB/s", T::NAME, lim, dt*1e3, (n*n*n) as f64/dt/1e6, s.bytes_per_iteration() as f64/dt/1e9);
}
fn main() {
    let n: usize = std::env::args().nth(1).unwrap().parse().unwrap();
    for lim in [FluxLimiter::Cda, FluxLimiter::LevermorePomraning, FluxLimiter::Sum] { run::<f32>(n, lim); run::<f64>(n, lim); }
}
