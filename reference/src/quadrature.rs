//! Small numerical-integration helpers for checking references.

/// Composite Simpson rule of `f` over `[a, b]` with `n` (rounded up to even) intervals.
pub fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let n = (n.max(2) + 1) & !1;
    let h = (b - a) / n as f64;
    let mut s = f(a) + f(b);
    for i in 1..n {
        let w = if i % 2 == 1 { 4.0 } else { 2.0 };
        s += w * f(a + i as f64 * h);
    }
    s * h / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simpson_is_fourth_order() {
        let exact = 1.0 - (-2.0f64).exp();
        let e1 = (simpson(|x| (-x).exp(), 0.0, 2.0, 8) - exact).abs();
        let e2 = (simpson(|x| (-x).exp(), 0.0, 2.0, 16) - exact).abs();
        let order = (e1 / e2).log2();
        assert!((order - 4.0).abs() < 0.1, "order {order}");
    }
}
