//! A hand-written SVG plot of a trace: stacked panels sharing the time axis, one
//! polyline per channel. No plotting crate: the output is small and dependency-free.

use std::fmt::Write as _;

use gantry::trace::Trace;

/// One panel: a title and the channels drawn in it.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Title (with unit).
    pub title: String,
    /// Indices of the trace channels drawn.
    pub channels: Vec<usize>,
}

const WIDTH: f64 = 1000.0;
const PANEL_H: f64 = 220.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 140.0;
const TOP: f64 = 30.0;
const GAP: f64 = 40.0;
const COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
];

/// Most points per polyline; longer traces keep each bucket's minimum and maximum.
pub const MAX_POINTS: usize = 2000;

/// Renders the panels as an SVG document.
pub fn svg(trace: &Trace, panels: &[Panel]) -> String {
    let height = TOP + panels.len() as f64 * (PANEL_H + GAP) + 20.0;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" viewBox="0 0 {WIDTH} {height}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let times = trace.times();
    let (t0, t1) = (
        times.first().copied().unwrap_or(0.0),
        times.last().copied().unwrap_or(1.0),
    );
    let t1 = if t1 > t0 { t1 } else { t0 + 1.0 };
    let plot_w = WIDTH - LEFT - RIGHT;
    for (k, panel) in panels.iter().enumerate() {
        let y_top = TOP + k as f64 * (PANEL_H + GAP);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &c in &panel.channels {
            for v in trace.column(c).filter(|v| v.is_finite()) {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        if !lo.is_finite() {
            (lo, hi) = (-1.0, 1.0);
        }
        if hi - lo < 1e-12 {
            (lo, hi) = (lo - 1.0, hi + 1.0);
        }
        let pad = (hi - lo) * 0.05;
        let (lo, hi) = (lo - pad, hi + pad);
        let x_of = |t: f64| LEFT + (t - t0) / (t1 - t0) * plot_w;
        let y_of = |v: f64| y_top + PANEL_H - (v - lo) / (hi - lo) * PANEL_H;
        let _ = writeln!(
            s,
            r##"<rect x="{LEFT}" y="{y_top}" width="{plot_w}" height="{PANEL_H}" fill="none" stroke="#888"/>"##
        );
        let _ = writeln!(
            s,
            r#"<text x="{LEFT}" y="{}" font-weight="bold">{}</text>"#,
            y_top - 8.0,
            escape(&panel.title)
        );
        for i in 0..=4 {
            let v = lo + (hi - lo) * i as f64 / 4.0;
            let y = y_of(v);
            let _ = writeln!(
                s,
                r##"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#eee"/><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"##,
                LEFT + plot_w,
                LEFT - 6.0,
                y + 4.0,
                tick(v)
            );
            let t = t0 + (t1 - t0) * i as f64 / 4.0;
            let x = x_of(t);
            let _ = writeln!(
                s,
                r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{} s</text>"#,
                y_top + PANEL_H + 14.0,
                tick(t)
            );
        }
        for (n, &c) in panel.channels.iter().enumerate() {
            let colour = COLOURS[n % COLOURS.len()];
            let values: Vec<f64> = trace.column(c).collect();
            let mut pts = String::new();
            for (t, v) in decimate(times, &values, MAX_POINTS) {
                let _ = write!(pts, "{:.2},{:.2} ", x_of(t), y_of(v));
            }
            let _ = writeln!(
                s,
                r#"<polyline fill="none" stroke="{colour}" stroke-width="1.3" points="{}"/>"#,
                pts.trim_end()
            );
            let name = trace.channels().get(c).map(String::as_str).unwrap_or("?");
            let ly = y_top + 16.0 + n as f64 * 16.0;
            let _ = writeln!(
                s,
                r#"<line x1="{:.1}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{colour}" stroke-width="2"/><text x="{:.1}" y="{:.1}">{}</text>"#,
                LEFT + plot_w + 10.0,
                LEFT + plot_w + 30.0,
                LEFT + plot_w + 36.0,
                ly + 4.0,
                escape(name)
            );
        }
    }
    s.push_str("</svg>\n");
    s
}

/// Keeps at most about `max` points: each bucket contributes its minimum and maximum in
/// time order, so peaks survive.
fn decimate(times: &[f64], values: &[f64], max: usize) -> Vec<(f64, f64)> {
    let n = times.len().min(values.len());
    if n <= max {
        return times
            .iter()
            .copied()
            .zip(values.iter().copied())
            .take(n)
            .collect();
    }
    let buckets = (max / 2).max(1);
    let size = n.div_ceil(buckets);
    let mut out = Vec::with_capacity(buckets * 2);
    for start in (0..n).step_by(size) {
        let end = (start + size).min(n);
        let idx = start..end;
        let lo = idx.clone().min_by(|&a, &b| values[a].total_cmp(&values[b]));
        let hi = idx.max_by(|&a, &b| values[a].total_cmp(&values[b]));
        if let (Some(a), Some(b)) = (lo, hi) {
            let (first, second) = if a <= b { (a, b) } else { (b, a) };
            out.push((times[first], values[first]));
            if second != first {
                out.push((times[second], values[second]));
            }
        }
    }
    out
}

fn tick(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(0.01..10_000.0).contains(&a) {
        format!("{v:.2e}")
    } else {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Renders an XY path plot: channel pairs `(x, y)` drawn as polylines in one square
/// frame with equal scales on both axes (a circle stays round), e.g. the set and the
/// actual path of a group's two axes.
pub fn xy_svg(trace: &Trace, title: &str, pairs: &[(usize, usize)]) -> String {
    const SIZE: f64 = 600.0;
    const MARGIN: f64 = 70.0;
    let side = SIZE - 2.0 * MARGIN;
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(cx, cy) in pairs {
        for (x, y) in trace.column(cx).zip(trace.column(cy)) {
            if x.is_finite() && y.is_finite() {
                (x_lo, x_hi) = (x_lo.min(x), x_hi.max(x));
                (y_lo, y_hi) = (y_lo.min(y), y_hi.max(y));
            }
        }
    }
    if !x_lo.is_finite() || !y_lo.is_finite() {
        (x_lo, x_hi, y_lo, y_hi) = (-1.0, 1.0, -1.0, 1.0);
    }
    // One scale for both: the larger span fills the square, the other is centred.
    let span = (x_hi - x_lo).max(y_hi - y_lo).max(1e-12) * 1.05;
    let (xc, yc) = ((x_lo + x_hi) / 2.0, (y_lo + y_hi) / 2.0);
    let (x0, y0) = (xc - span / 2.0, yc - span / 2.0);
    let px = |x: f64| MARGIN + (x - x0) / span * side;
    let py = |y: f64| MARGIN + side - (y - y0) / span * side;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{SIZE}" height="{SIZE}" viewBox="0 0 {SIZE} {SIZE}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r##"<rect x="{MARGIN}" y="{MARGIN}" width="{side}" height="{side}" fill="none" stroke="#888"/>"##
    );
    let _ = writeln!(
        s,
        r#"<text x="{MARGIN}" y="{}" font-weight="bold">{}</text>"#,
        MARGIN - 12.0,
        escape(title)
    );
    for i in 0..=4 {
        let f = i as f64 / 4.0;
        let (x, y) = (x0 + span * f, y0 + span * f);
        let _ = writeln!(
            s,
            r##"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"##,
            px(x),
            MARGIN + side + 16.0,
            tick(x),
            MARGIN - 6.0,
            py(y) + 4.0,
            tick(y)
        );
    }
    let names = trace.channels();
    for (k, &(cx, cy)) in pairs.iter().enumerate() {
        let colour = COLOURS.get(k % COLOURS.len()).copied().unwrap_or("#000");
        let points: Vec<String> = trace
            .column(cx)
            .zip(trace.column(cy))
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|(x, y)| format!("{:.2},{:.2}", px(x), py(y)))
            .collect();
        let _ = writeln!(
            s,
            r#"<polyline fill="none" stroke="{colour}" stroke-width="1.2" points="{}"/>"#,
            points.join(" ")
        );
        let label = format!(
            "{} / {}",
            names.get(cx).map_or("?", String::as_str),
            names.get(cy).map_or("?", String::as_str)
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" fill="{colour}">{}</text>"#,
            MARGIN + 8.0,
            MARGIN + 16.0 + 14.0 * k as f64,
            escape(&label)
        );
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svg_has_one_polyline_per_channel_and_keeps_peaks() {
        let mut t = Trace::new(vec!["x.p".into(), "y.p".into(), "x.v".into()], 10_000);
        for i in 0..10_000 {
            let v = if i == 5_000 {
                100.0
            } else {
                (i as f64 * 0.01).sin()
            };
            t.push(i as f64 * 0.001, &[v, -v, 2.0 * v]).unwrap();
        }
        let panels = [
            Panel {
                title: "position <units>".into(),
                channels: vec![0, 1],
            },
            Panel {
                title: "velocity".into(),
                channels: vec![2],
            },
        ];
        let doc = svg(&t, &panels);
        assert!(doc.starts_with("<svg") && doc.trim_end().ends_with("</svg>"));
        assert_eq!(doc.matches("<polyline").count(), 3);
        assert!(doc.contains("position &lt;units&gt;"));
        let pts = doc
            .split("points=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        assert!(pts.split(' ').count() <= MAX_POINTS + 2);
        let d = decimate(t.times(), &t.column(0).collect::<Vec<_>>(), MAX_POINTS);
        assert!(
            d.iter().any(|&(_, v)| v == 100.0),
            "the spike survives decimation"
        );
    }

    #[test]
    fn an_xy_plot_keeps_equal_scales_so_a_circle_stays_round() {
        let mut t = Trace::new(vec!["x.set".into(), "y.set".into()], 400);
        for i in 0..=360 {
            let a = (i as f64).to_radians();
            t.push(
                i as f64 * 0.01,
                &[10.0 + 5.0 * a.cos(), -3.0 + 5.0 * a.sin()],
            )
            .unwrap();
        }
        let doc = xy_svg(&t, "path", &[(0, 1)]);
        let points: Vec<(f64, f64)> = doc
            .split("points=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .split(' ')
            .map(|p| {
                let (x, y) = p.split_once(',').unwrap();
                (x.parse().unwrap(), y.parse().unwrap())
            })
            .collect();
        let (cx, cy) = points
            .iter()
            .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
        let (cx, cy) = (cx / points.len() as f64, cy / points.len() as f64);
        let radii: Vec<f64> = points.iter().map(|(x, y)| (x - cx).hypot(y - cy)).collect();
        let (lo, hi) = radii
            .iter()
            .fold((f64::MAX, 0.0_f64), |(l, h), r| (l.min(*r), h.max(*r)));
        assert!(hi - lo < 0.05 * hi, "not round: {lo} .. {hi}");
        assert!(doc.contains("x.set / y.set"));
    }
}
