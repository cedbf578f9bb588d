//! One segment of a cam table: a polynomial of degree <= 5 in the normalised coordinate
//! `u = (x - x0) / h ∈ [0, 1]`. Normalising keeps the coefficients of the order of the
//! slave values whatever the master spacing (`h⁵` in a denominator would overflow or lose
//! digits for short or long segments), and `u = 0` gives the first point's slave exactly.

use super::CamSample;

/// Bisection steps for a root of a monotone piece: 2⁻⁶⁰ of the unit interval is below
/// one ulp of any `u` in it.
const BISECTION_STEPS: u32 = 60;

/// Coefficients `b[k]` of `Σ b[k] u^k`.
pub(crate) type Coeffs = [f64; 6];

/// One segment: master start `x0`, length `h > 0`, coefficients in `u`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Segment {
    /// Master position where the segment starts.
    pub(crate) x0: f64,
    /// Master length of the segment (> 0).
    pub(crate) h: f64,
    /// Polynomial in `u = (x - x0) / h`.
    pub(crate) c: Coeffs,
}

/// Position, first and second derivative at one end of a segment (with respect to the
/// master, not `u`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Knot {
    pub(crate) p: f64,
    pub(crate) d1: f64,
    pub(crate) d2: f64,
}

impl Segment {
    /// A straight line from `p0` to `p1`.
    pub(crate) fn linear(x0: f64, h: f64, p0: f64, p1: f64) -> Self {
        Segment {
            x0,
            h,
            c: [p0, p1 - p0, 0.0, 0.0, 0.0, 0.0],
        }
    }

    /// The spline's cubic from its start (slave, d1, d2 in `k0`) and the d2 `a1` at its
    /// end: d2 is linear over the segment. Its slave at the end is the next point's up to
    /// rounding (the spline's d1 was solved for that); evaluation at a point uses the
    /// segment starting there, so the table's values come back exactly.
    pub(crate) fn cubic(x0: f64, h: f64, k0: Knot, a1: f64) -> Self {
        let h2 = h * h;
        Segment {
            x0,
            h,
            c: [
                k0.p,
                k0.d1 * h,
                k0.d2 * h2 / 2.0,
                (a1 - k0.d2) * h2 / 6.0,
                0.0,
                0.0,
            ],
        }
    }

    /// The quintic matching position, first and second derivative at both ends (Hermite
    /// quintic; Biagiotti & Melchiorri, "Trajectory Planning for Automatic Machines and
    /// Robots", §2.1.7, in normalised form: `b_k = a_k h^k`).
    pub(crate) fn quintic(x0: f64, h: f64, k0: Knot, k1: Knot) -> Self {
        let dp = k1.p - k0.p;
        let (v0, v1) = (k0.d1 * h, k1.d1 * h);
        let (a0, a1) = (k0.d2 * h * h, k1.d2 * h * h);
        Segment {
            x0,
            h,
            c: [
                k0.p,
                v0,
                a0 / 2.0,
                10.0 * dp - 6.0 * v0 - 4.0 * v1 - 1.5 * a0 + 0.5 * a1,
                -15.0 * dp + 8.0 * v0 + 7.0 * v1 + 1.5 * a0 - a1,
                6.0 * dp - 3.0 * (v0 + v1) - 0.5 * (a0 - a1),
            ],
        }
    }

    /// Slave, d1 and d2 at master position `x` (not clamped to the segment).
    pub(crate) fn sample(&self, x: f64) -> CamSample {
        self.sample_u((x - self.x0) / self.h)
    }

    /// Slave, d1 and d2 at `u`.
    pub(crate) fn sample_u(&self, u: f64) -> CamSample {
        // The three Horner sums of the polynomial and its derivatives written out (the
        // cycle evaluates this for every cammed axis: no derivative arrays, one division).
        let [c0, c1, c2, c3, c4, c5] = self.c;
        let p = c0 + u * (c1 + u * (c2 + u * (c3 + u * (c4 + u * c5))));
        let dp = c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + u * (5.0 * c5))));
        let ddp = 2.0 * c2 + u * (6.0 * c3 + u * (12.0 * c4 + u * (20.0 * c5)));
        let inv_h = 1.0 / self.h;
        CamSample {
            slave: p,
            d1: dp * inv_h,
            d2: ddp * inv_h * inv_h,
        }
    }

    /// The largest |d1| and |d2| over the segment: exact up to rounding, since each is a
    /// polynomial whose extremes lie at the ends or at roots of its derivative, found in
    /// closed form or by bisection on monotone pieces.
    pub(crate) fn max_abs_derivatives(&self) -> (f64, f64) {
        let d = derivative(&self.c);
        let dd = derivative(&d);
        (
            max_abs_on_unit(&d) / self.h,
            max_abs_on_unit(&dd) / (self.h * self.h),
        )
    }

    /// Whether every coefficient is finite.
    pub(crate) fn is_finite(&self) -> bool {
        self.c.iter().all(|c| c.is_finite())
    }
}

/// `Σ c[k] u^k` by Horner's rule.
fn horner(c: &Coeffs, u: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ck| acc * u + ck)
}

/// Coefficients of the derivative with respect to `u`.
fn derivative(c: &Coeffs) -> Coeffs {
    let mut d = [0.0; 6];
    for ((k, dk), ck) in d.iter_mut().enumerate().zip(c.iter().skip(1)) {
        *dk = ck * (k + 1) as f64;
    }
    d
}

/// max |p(u)| for u in [0, 1].
fn max_abs_on_unit(p: &Coeffs) -> f64 {
    let mut roots = [0.0; 5];
    let n = roots_in(&derivative(p), 0.0, 1.0, &mut roots);
    roots
        .iter()
        .take(n)
        .chain([0.0, 1.0].iter())
        .map(|&u| horner(p, u).abs())
        .fold(0.0, f64::max)
}

/// Roots of `p` in `[a, b]` (at most 5 kept: `p` has degree <= 5; a polynomial that is
/// zero everywhere reports none). The roots of `p'` cut `[a, b]` into pieces on which `p`
/// is monotone; a piece whose ends differ in sign holds exactly one root, found by
/// bisection. Recursion depth is the degree.
fn roots_in(p: &Coeffs, a: f64, b: f64, out: &mut [f64; 5]) -> usize {
    let d = derivative(p);
    if p.iter().skip(1).all(|&c| c == 0.0) {
        return 0; // constant: no isolated roots
    }
    let mut crit = [0.0; 5];
    let nc = roots_in(&d, a, b, &mut crit);
    let mut n = 0;
    let mut push = |u: f64, n: &mut usize| {
        if let Some(slot) = out.get_mut(*n) {
            *slot = u;
            *n += 1;
        }
    };
    let mut lo = a;
    for &hi in crit.iter().take(nc).chain([b].iter()) {
        let (flo, fhi) = (horner(p, lo), horner(p, hi));
        if flo == 0.0 {
            push(lo, &mut n);
        } else if flo.signum() != fhi.signum() && fhi != 0.0 {
            let (mut l, mut r) = (lo, hi);
            for _ in 0..BISECTION_STEPS {
                let m = 0.5 * (l + r);
                if horner(p, m).signum() == flo.signum() {
                    l = m;
                } else {
                    r = m;
                }
            }
            push(0.5 * (l + r), &mut n);
        }
        lo = hi;
    }
    if horner(p, b) == 0.0 {
        push(b, &mut n);
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_of_a_cubic_with_three_roots_in_the_unit_interval() {
        // (u - 0.1)(u - 0.5)(u - 0.8) = u³ - 1.4u² + 0.53u - 0.04
        let p = [-0.04, 0.53, -1.4, 1.0, 0.0, 0.0];
        let mut r = [0.0; 5];
        let n = roots_in(&p, 0.0, 1.0, &mut r);
        assert_eq!(n, 3);
        for (got, want) in r.iter().zip([0.1, 0.5, 0.8]) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn quintic_matches_both_ends() {
        let k0 = Knot {
            p: 1.0,
            d1: -2.0,
            d2: 3.0,
        };
        let k1 = Knot {
            p: 5.0,
            d1: 0.5,
            d2: -7.0,
        };
        let s = Segment::quintic(2.0, 0.7, k0, k1);
        let a = s.sample(2.0);
        let b = s.sample_u(1.0);
        for (got, want) in [
            (a.slave, 1.0),
            (a.d1, -2.0),
            (a.d2, 3.0),
            (b.slave, 5.0),
            (b.d1, 0.5),
            (b.d2, -7.0),
        ] {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn max_of_a_parabola_is_at_its_vertex() {
        // p = 4u(1-u): max 1 at u = 0.5, derivative 4 - 8u: max |.| = 4 at the ends.
        let s = Segment {
            x0: 0.0,
            h: 2.0,
            c: [0.0, 4.0, -4.0, 0.0, 0.0, 0.0],
        };
        assert_eq!(max_abs_on_unit(&s.c), 1.0);
        let (d1, d2) = s.max_abs_derivatives();
        assert_eq!(d1, 2.0);
        assert_eq!(d2, 2.0);
    }
}
