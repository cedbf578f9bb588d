//! The live status table: one row per axis, redrawn in place on a terminal and printed
//! frame by frame otherwise (CI logs).

use std::fmt::Write as _;

use gantry_kernel::axis::status::AxisStatus;

/// One row of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Axis name.
    pub axis: String,
    /// Axis type ("real", "simulated", "virtual", "external", "shadow").
    pub axis_type: &'static str,
    /// The axis' status.
    pub status: AxisStatus,
    /// Status of the axis' last command ("Busy", "Done", …).
    pub command: String,
    /// Error text, if any.
    pub error: String,
}

/// Renders a frame: a header with the time and one line per axis.
pub fn render(time_s: f64, rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "t = {time_s:7.3} s");
    let _ = writeln!(
        s,
        "{:<5} {:<9} {:<18} {:<14} {:>11} {:>10} {:>10} {:<6} {:<15} error",
        "axis", "type", "state", "slope", "position", "velocity", "accel", "homed", "command"
    );
    for r in rows {
        let st = &r.status;
        let _ = writeln!(
            s,
            "{:<5} {:<9} {:<18} {:<14} {:>11.4} {:>10.3} {:>10.2} {:<6} {:<15} {}",
            r.axis,
            r.axis_type,
            st.state.name(),
            st.slope.name(),
            st.set.p,
            st.set.v,
            st.set.a,
            if st.bits.homed { "yes" } else { "no" },
            r.command,
            r.error
        );
    }
    s
}

/// Writes frames: on a terminal each frame replaces the previous one in place.
#[derive(Debug)]
pub struct Live {
    tty: bool,
    last_lines: usize,
}

impl Live {
    /// `tty`: whether stdout is a terminal.
    pub fn new(tty: bool) -> Self {
        Self { tty, last_lines: 0 }
    }

    /// The text that shows `frame` (cursor movement included on a terminal).
    pub fn frame(&mut self, frame: &str) -> String {
        let mut out = String::new();
        if self.tty && self.last_lines > 0 {
            // Cursor up over the previous frame, then clear to the end of the screen.
            let _ = write!(out, "\x1b[{}A\x1b[J", self.last_lines);
        }
        out.push_str(frame);
        if !self.tty {
            out.push('\n');
        }
        self.last_lines = frame.lines().count();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_one_line_per_axis_and_redraws_in_place_on_a_tty() {
        let row = Row {
            axis: "x".into(),
            axis_type: "real",
            status: AxisStatus::default(),
            command: "Done".into(),
            error: String::new(),
        };
        let f = render(
            1.5,
            &[
                row.clone(),
                Row {
                    axis: "y".into(),
                    axis_type: "virtual",
                    ..row
                },
            ],
        );
        assert_eq!(f.lines().count(), 4);
        assert!(f.contains("Disabled") && f.contains("Stopped"));
        assert!(f.contains(" type ") && f.contains(" virtual "), "{f}");
        let mut live = Live::new(true);
        assert!(!live.frame(&f).contains('\x1b'));
        assert!(live.frame(&f).starts_with("\x1b[4A"));
        let mut plain = Live::new(false);
        plain.frame(&f);
        assert!(!plain.frame(&f).contains('\x1b'));
    }
}
