//! The first and second derivatives at a table's points: from the C2 cubic spline
//! (natural or periodic) for [`super::Interpolation::Cubic`], and from the local parabola
//! through each point and its neighbours for [`super::Interpolation::Quintic`].
//!
//! Only run at construction; allocates.

use super::CamPoint;

/// (d1, d2) at every point, in order.
pub(crate) type KnotDerivatives = Vec<(f64, f64)>;

/// Segment lengths and slopes: `h[i] = x[i+1] - x[i]`, `delta[i] = (y[i+1] - y[i]) / h[i]`.
fn lengths_and_slopes(points: &[CamPoint]) -> (Vec<f64>, Vec<f64>) {
    points
        .windows(2)
        .map(|w| match w {
            [a, b] => {
                let h = b.master - a.master;
                (h, (b.slave - a.slave) / h)
            }
            _ => (1.0, 0.0), // windows(2) yields only pairs
        })
        .unzip()
}

/// The C2 cubic spline's second derivatives `M` at the points and the first derivatives
/// that go with them. Natural (`M = 0` at both ends) unless `periodic`, where the
/// unknowns are `M[0..n-1]` with `M[n-1] = M[0]` and the first point's left neighbour is
/// the one before the last (the period wraps). The system (de Boor, "A Practical Guide to
/// Splines", ch. IV) is `h[i-1] M[i-1] + 2 (h[i-1] + h[i]) M[i] + h[i] M[i+1] =
/// 6 (delta[i] - delta[i-1])`: strictly diagonally dominant, so elimination without
/// pivoting is stable. `points.len() >= 2`, and `>= 3` if periodic (checked by the caller).
pub(crate) fn cubic_spline(points: &[CamPoint], periodic: bool) -> KnotDerivatives {
    let (h, delta) = lengths_and_slopes(points);
    let segments = h.len();
    // Row i of the system for point i, given its left segment l and right segment r.
    let row = |l: usize, r: usize| {
        let (hl, hr) = (
            h.get(l).copied().unwrap_or(1.0),
            h.get(r).copied().unwrap_or(1.0),
        );
        let (dl, dr) = (
            delta.get(l).copied().unwrap_or(0.0),
            delta.get(r).copied().unwrap_or(0.0),
        );
        (hl, 2.0 * (hl + hr), hr, 6.0 * (dr - dl))
    };
    let m: Vec<f64> = if periodic {
        // Unknowns M[0..segments], point i's left segment is (i - 1) mod segments.
        let rows: Vec<_> = (0..segments)
            .map(|i| row((i + segments - 1) % segments, i))
            .collect();
        let mut m = solve_cyclic(&rows);
        m.push(m.first().copied().unwrap_or(0.0));
        m
    } else {
        let rows: Vec<_> = (1..segments).map(|i| row(i - 1, i)).collect();
        let mut m = vec![0.0];
        m.extend(solve_tridiagonal(&rows));
        m.push(0.0);
        m
    };
    // d1 at point i from its right segment; at the last point from its left one.
    let mut out: KnotDerivatives = Vec::with_capacity(points.len());
    for ((&hi, &di), mw) in h.iter().zip(&delta).zip(m.windows(2)) {
        if let [m0, m1] = mw {
            out.push((di - hi * (2.0 * m0 + m1) / 6.0, *m0));
        }
    }
    if let (Some(&hl), Some(&dl), [.., m0, m1]) = (h.last(), delta.last(), m.as_slice()) {
        out.push((dl + hl * (m0 + 2.0 * m1) / 6.0, *m1));
    }
    out
}

/// One row `(sub, diag, sup, rhs)` of a tridiagonal system.
type Row = (f64, f64, f64, f64);

/// Thomas algorithm; the first row's `sub` and the last row's `sup` are ignored.
fn solve_tridiagonal(rows: &[Row]) -> Vec<f64> {
    let last = rows.len().saturating_sub(1);
    let mut forward: Vec<(f64, f64)> = Vec::with_capacity(rows.len());
    let (mut c_prev, mut d_prev) = (0.0, 0.0);
    for (i, &(a, b, c, r)) in rows.iter().enumerate() {
        let a = if i == 0 { 0.0 } else { a };
        let c = if i == last { 0.0 } else { c };
        let pivot = b - a * c_prev;
        c_prev = c / pivot;
        d_prev = (r - a * d_prev) / pivot;
        forward.push((c_prev, d_prev));
    }
    let mut x = vec![0.0; rows.len()];
    let mut next = 0.0;
    for (xi, &(c, d)) in x.iter_mut().zip(&forward).rev() {
        *xi = d - c * next;
        next = *xi;
    }
    x
}

/// A cyclic tridiagonal system: row 0's `sub` multiplies the last unknown and the last
/// row's `sup` the first. Sherman–Morrison on the tridiagonal part (Press et al.,
/// "Numerical Recipes", §2.7) for 3 or more unknowns; 2 unknowns (where the corners fall
/// on the off-diagonal) and 1 solved directly.
fn solve_cyclic(rows: &[Row]) -> Vec<f64> {
    match rows {
        [] => Vec::new(),
        [(a, b, c, r)] => vec![r / (a + b + c)],
        [(a0, b0, c0, r0), (a1, b1, c1, r1)] => {
            // Row 0: b0 x0 + (a0 + c0) x1 = r0; row 1: (a1 + c1) x0 + b1 x1 = r1.
            let (p, q, s, t) = (*b0, a0 + c0, a1 + c1, *b1);
            let det = p * t - q * s;
            vec![(r0 * t - q * r1) / det, (p * r1 - s * r0) / det]
        }
        [(alpha, b0, ..), .., (.., beta, _)] => {
            let (alpha, beta) = (*alpha, *beta);
            let gamma = -b0;
            let last = rows.len() - 1;
            let modified: Vec<Row> = rows
                .iter()
                .enumerate()
                .map(|(i, &(a, b, c, r))| {
                    let b = if i == 0 {
                        b - gamma
                    } else if i == last {
                        b - alpha * beta / gamma
                    } else {
                        b
                    };
                    (a, b, c, r)
                })
                .collect();
            let x = solve_tridiagonal(&modified);
            let u_rows: Vec<Row> = modified
                .iter()
                .enumerate()
                .map(|(i, &(a, b, c, _))| {
                    let u = if i == 0 {
                        gamma
                    } else if i == last {
                        beta
                    } else {
                        0.0
                    };
                    (a, b, c, u)
                })
                .collect();
            let z = solve_tridiagonal(&u_rows);
            let ends = |v: &[f64]| {
                (
                    v.first().copied().unwrap_or(0.0),
                    v.last().copied().unwrap_or(0.0),
                )
            };
            let ((x0, xl), (z0, zl)) = (ends(&x), ends(&z));
            let fact = (x0 + alpha * xl / gamma) / (1.0 + z0 + alpha * zl / gamma);
            x.iter().zip(&z).map(|(xi, zi)| xi - fact * zi).collect()
        }
    }
}

/// Which of the parabola's three points the derivatives are wanted at.
#[derive(Clone, Copy)]
enum At {
    First,
    Middle,
    Last,
}

/// d1 and d2 of the parabola through `a`, `b`, `c` (master strictly increasing) at `at`.
fn parabola(a: CamPoint, b: CamPoint, c: CamPoint, at: At) -> (f64, f64) {
    let (ha, hc) = (b.master - a.master, c.master - b.master);
    let (da, dc) = ((b.slave - a.slave) / ha, (c.slave - b.slave) / hc);
    let curvature = (dc - da) / (ha + hc); // half the second derivative
    let d2 = 2.0 * curvature;
    let d1 = match at {
        At::First => da - curvature * ha,
        At::Middle => (hc * da + ha * dc) / (ha + hc),
        At::Last => dc + curvature * hc,
    };
    (d1, d2)
}

/// Quintic's point derivatives: d1 and d2 of the parabola through the point and its two
/// neighbours (local: moving one point changes only the two segments on either side of it
/// and their neighbours, unlike the spline). A point whose slave equals a neighbour's
/// (a dwell) gets d1 = d2 = 0, so a segment between two equal slave values is exactly flat
/// and a rise between two dwells is the rest-to-rest 3-4-5 polynomial. Not periodic: the
/// end points use the parabola through the first (last) three points, or the straight line
/// with two points. Periodic: the neighbours wrap (the point before the first is the one
/// before the last, shifted back by one period and one slave rise), so the first and the
/// last point get the same d1 and d2. `points.len() >= 2`, `>= 3` if periodic.
pub(crate) fn local_parabolas(points: &[CamPoint], periodic: bool) -> KnotDerivatives {
    let n = points.len();
    let (first, last) = match (points.first(), points.last()) {
        (Some(f), Some(l)) => (*f, *l),
        _ => return Vec::new(),
    };
    let (period, rise) = (last.master - first.master, last.slave - first.slave);
    let shifted = |p: CamPoint, k: f64| CamPoint {
        master: p.master + k * period,
        slave: p.slave + k * rise,
    };
    let at = |i: usize| points.get(i).copied();
    (0..n)
        .map(|i| {
            let here = at(i).unwrap_or(first);
            let prev = match i.checked_sub(1) {
                Some(j) => at(j),
                None if periodic => at(n.saturating_sub(2)).map(|p| shifted(p, -1.0)),
                None => None,
            };
            let next = match at(i + 1) {
                Some(p) => Some(p),
                None if periodic => at(1).map(|p| shifted(p, 1.0)),
                None => None,
            };
            // Compared unshifted (a shifted copy may differ by rounding): across the wrap,
            // the segment before the first point is the last segment.
            let equal = |a: usize, b: usize| match (at(a), at(b)) {
                (Some(p), Some(q)) => p.slave == q.slave,
                _ => false,
            };
            let dwell_before = match i.checked_sub(1) {
                Some(j) => equal(j, i),
                None => periodic && equal(n.saturating_sub(2), n - 1),
            };
            let dwell_after = if i + 1 < n {
                equal(i, i + 1)
            } else {
                periodic && equal(0, 1)
            };
            let dwell = dwell_before || dwell_after;
            if dwell {
                return (0.0, 0.0);
            }
            match (prev, next) {
                (Some(p), Some(q)) => parabola(p, here, q, At::Middle),
                (None, Some(q)) => match at(i + 2) {
                    Some(r) => parabola(here, q, r, At::First),
                    None => ((q.slave - here.slave) / (q.master - here.master), 0.0),
                },
                (Some(p), None) => match i.checked_sub(2).and_then(at) {
                    Some(o) => parabola(o, p, here, At::Last),
                    None => ((here.slave - p.slave) / (here.master - p.master), 0.0),
                },
                (None, None) => (0.0, 0.0),
            }
        })
        .collect()
}
