//! The drive's touch probe (CiA 402-2 and ETG.6010 §14: 0x60B8 touch probe function,
//! 0x60B9 touch probe status, 0x60BA–0x60BD the latched positions) and the switch cams
//! on the drive's own travel that its digital inputs (0x60FD) read.
//!
//! A touch probe latches the position at the instant of an edge, in hardware, so the
//! value is exact to the count at any speed — what homing needs and what the cycle-sampled
//! position cannot give. Two probes, each with its function byte (probe 2 in the high
//! byte): enable; first event or continuous; trigger on the probe input or on the
//! encoder's zero impulse (index pulse); sample the positive edge, the negative edge, or
//! both. The simulated drive wires both probe inputs to its home switch (bit 2 of 0x60FD),
//! as commissioning engineers wire a drive's probe input for homing.
//!
//! Rules as ETG.6010 gives them and drives follow: the rising edge of a probe's enable bit
//! arms it (stored bits cleared); clearing the enable clears its status; in first-event
//! mode each edge latches once and stays stored until re-armed — by the enable's rising
//! edge, or by clearing that edge's sample-enable bit and setting it again; in continuous
//! mode every event overwrites the value. Status bits 6/7 (probe 2: 14/15, user-defined in
//! the profile) toggle with each positive/negative latch, so a master sees every new
//! value in continuous mode too. A source the simulated drive does not have (bits 2–3 =
//! 10: the source in 0x60D0; 11: reserved) never triggers. The zero impulse is a mark, not
//! a level: it latches on the positive-edge sample only.

use crate::plant::switches::SwitchCam;

/// Function bits of one probe (probe `n` at bit `8·n`).
pub mod function {
    /// Enable the probe.
    pub const ENABLE: u16 = 1 << 0;
    /// Continuous (else the first event only).
    pub const CONTINUOUS: u16 = 1 << 1;
    /// Trigger source, bits 2–3: 00 the probe input, 01 the encoder's zero impulse.
    pub const SOURCE_MASK: u16 = 0b11 << 2;
    /// Source: the encoder's zero impulse.
    pub const SOURCE_ZERO_IMPULSE: u16 = 0b01 << 2;
    /// Sample the positive edge.
    pub const POSITIVE_EDGE: u16 = 1 << 4;
    /// Sample the negative edge.
    pub const NEGATIVE_EDGE: u16 = 1 << 5;
}

/// Status bits of one probe (probe `n` at bit `8·n`).
pub mod status {
    /// The probe is enabled.
    pub const ENABLED: u16 = 1 << 0;
    /// A positive-edge value is stored.
    pub const POSITIVE_STORED: u16 = 1 << 1;
    /// A negative-edge value is stored.
    pub const NEGATIVE_STORED: u16 = 1 << 2;
    /// Toggles with each positive-edge latch.
    pub const POSITIVE_TOGGLE: u16 = 1 << 6;
    /// Toggles with each negative-edge latch.
    pub const NEGATIVE_TOGGLE: u16 = 1 << 7;
}

/// Probes per drive.
pub const PROBES: usize = 2;

/// An edge of a signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edge {
    /// Becoming active.
    Positive,
    /// Becoming inactive.
    Negative,
}

/// What can trigger a probe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// The probe input (the home switch).
    Input,
    /// The encoder's zero impulse (index pulse).
    ZeroImpulse,
}

/// An edge of a signal at a position (counts): the first count of the new state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Event {
    /// Which signal.
    pub signal: Signal,
    /// Which edge.
    pub edge: Edge,
    /// Where (counts, the drive's full position).
    pub at: i64,
}

/// The two probes: 0x60B8, 0x60B9 and the four latched values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TouchProbe {
    function: u16,
    status: u16,
    /// `[probe][edge]`: 0x60BA, 0x60BB, 0x60BC, 0x60BD.
    values: [[i32; 2]; PROBES],
}

impl TouchProbe {
    /// 0x60B8 as last written.
    pub fn function(&self) -> u16 {
        self.function
    }

    /// 0x60B9.
    pub fn status(&self) -> u16 {
        self.status
    }

    /// The value latched by probe `probe` (0 or 1) on `edge` (0x60BA–0x60BD); 0 for a
    /// probe that does not exist.
    pub fn value(&self, probe: usize, edge: Edge) -> i32 {
        self.values
            .get(probe)
            .and_then(|v| v.get(edge_slot(edge)))
            .copied()
            .unwrap_or(0)
    }

    /// The master writes 0x60B8.
    pub fn set_function(&mut self, f: u16) {
        for n in 0..PROBES {
            let shift = 8 * n;
            let old = (self.function >> shift) & 0xFF;
            let new = (f >> shift) & 0xFF;
            let mut st = (self.status >> shift) & 0xFF;
            if new & function::ENABLE == 0 {
                st = 0;
            } else if old & function::ENABLE == 0 {
                // The enable's rising edge arms the probe.
                st = status::ENABLED;
            } else {
                // Clearing a sample-enable bit re-arms that edge.
                if new & function::POSITIVE_EDGE == 0 {
                    st &= !status::POSITIVE_STORED;
                }
                if new & function::NEGATIVE_EDGE == 0 {
                    st &= !status::NEGATIVE_STORED;
                }
            }
            self.status = (self.status & !(0xFF << shift)) | (st << shift);
        }
        self.function = f;
    }

    /// An event happened: every probe armed for it latches its position.
    pub fn event(&mut self, e: Event) {
        for n in 0..PROBES {
            let shift = 8 * n;
            let f = (self.function >> shift) & 0xFF;
            if f & function::ENABLE == 0 {
                continue;
            }
            let source = f & function::SOURCE_MASK;
            let wanted = match e.signal {
                Signal::Input => source == 0,
                Signal::ZeroImpulse => {
                    source == function::SOURCE_ZERO_IMPULSE && e.edge == Edge::Positive
                }
            };
            let (sample, stored, toggle) = match e.edge {
                Edge::Positive => (
                    function::POSITIVE_EDGE,
                    status::POSITIVE_STORED,
                    status::POSITIVE_TOGGLE,
                ),
                Edge::Negative => (
                    function::NEGATIVE_EDGE,
                    status::NEGATIVE_STORED,
                    status::NEGATIVE_TOGGLE,
                ),
            };
            let st = (self.status >> shift) & 0xFF;
            let free = f & function::CONTINUOUS != 0 || st & stored == 0;
            if wanted && f & sample != 0 && free {
                // The value is the 32-bit position actual value at the edge.
                if let Some(v) = self
                    .values
                    .get_mut(n)
                    .and_then(|v| v.get_mut(edge_slot(e.edge)))
                {
                    *v = e.at as i32;
                }
                let st = (st | stored) ^ toggle;
                self.status = (self.status & !(0xFF << shift)) | (st << shift);
            }
        }
    }
}

fn edge_slot(edge: Edge) -> usize {
    match edge {
        Edge::Positive => 0,
        Edge::Negative => 1,
    }
}

/// 0x60FD bits the cams drive: negative limit, positive limit, home switch.
pub const SWITCH_INPUTS: u8 = 3;
/// Input of the home switch (bit 2 of 0x60FD), the probe input.
pub const HOME_INPUT: u8 = 2;

/// Switch cams on the drive's own travel, one per 0x60FD switch bit (0 negative limit, 1
/// positive limit, 2 home). The bits report the switch *function* active (CiA 402: 1 =
/// active), as a drive configured for its contacts' type reports them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveSwitches {
    cams: [Option<SwitchCam>; SWITCH_INPUTS as usize],
}

impl DriveSwitches {
    /// The cams, each on its input (a cam on an input above 2 is ignored: check with
    /// [`crate::plant::switches::check_cams`] and [`SWITCH_INPUTS`] first).
    pub fn new(cams: &[SwitchCam]) -> Self {
        let mut s = Self::default();
        for c in cams {
            if let Some(slot) = s.cams.get_mut(usize::from(c.input)) {
                *slot = Some(*c);
            }
        }
        s
    }

    /// The cam on 0x60FD bit `input`, if one is wired.
    pub fn cam(&self, input: u8) -> Option<SwitchCam> {
        self.cams.get(usize::from(input)).copied().flatten()
    }

    /// Whether any cam is wired.
    pub fn any(&self) -> bool {
        self.cams.iter().any(Option::is_some)
    }

    /// 0x60FD at position `counts`.
    pub fn digital_inputs(&self, counts: i64) -> u32 {
        self.cams
            .iter()
            .enumerate()
            .filter(|(_, c)| c.is_some_and(|c| c.actuated(counts)))
            .fold(0, |bits, (i, _)| bits | 1 << i)
    }

    /// The home switch's edges on the way from count `from` to count `to`, in the order
    /// of travel (at most two: on and off a narrow cam in one step).
    pub fn home_edges(&self, from: i64, to: i64) -> [Option<Event>; 2] {
        let mut out = [None; 2];
        let Some(Some(cam)) = self.cams.get(usize::from(HOME_INPUT)) else {
            return out;
        };
        let event = |edge, at| {
            Some(Event {
                signal: Signal::Input,
                edge,
                at,
            })
        };
        if to > from {
            if from < cam.from && cam.from <= to {
                out[0] = event(Edge::Positive, cam.from);
            }
            if from <= cam.to && cam.to < to {
                out[1] = event(Edge::Negative, cam.to + 1);
            }
        } else if to < from {
            if to <= cam.to && cam.to < from {
                out[0] = event(Edge::Positive, cam.to);
            }
            if to < cam.from && cam.from <= from {
                out[1] = event(Edge::Negative, cam.from - 1);
            }
        }
        out
    }
}

/// The first index pulse passed on the way from count `from` to count `to` (the index at
/// `index_at` in every revolution of `counts_per_rev`), as an event.
pub fn index_crossing(from: i64, to: i64, index_at: i64, counts_per_rev: i64) -> Option<Event> {
    let rev = counts_per_rev.max(1);
    let at = if to > from {
        // The first index count above `from`.
        let k = (from - index_at).div_euclid(rev) + 1;
        Some(index_at + k * rev).filter(|&p| p <= to)
    } else if to < from {
        let k = (from - index_at - 1).div_euclid(rev);
        Some(index_at + k * rev).filter(|&p| p >= to)
    } else {
        None
    }?;
    Some(Event {
        signal: Signal::ZeroImpulse,
        edge: Edge::Positive,
        at,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const P1_INPUT_BOTH: u16 = function::ENABLE | function::POSITIVE_EDGE | function::NEGATIVE_EDGE;

    fn home(at: i64, edge: Edge) -> Event {
        Event {
            signal: Signal::Input,
            edge,
            at,
        }
    }

    #[test]
    fn first_event_latches_once_until_rearmed() {
        let mut tp = TouchProbe::default();
        tp.set_function(P1_INPUT_BOTH);
        assert_eq!(tp.status(), status::ENABLED);
        tp.event(home(100, Edge::Positive));
        tp.event(home(200, Edge::Positive));
        assert_eq!(tp.value(0, Edge::Positive), 100);
        assert_eq!(
            tp.status(),
            status::ENABLED | status::POSITIVE_STORED | status::POSITIVE_TOGGLE
        );
        tp.event(home(150, Edge::Negative));
        assert_eq!(tp.value(0, Edge::Negative), 150);
        // Clearing the positive sample bit re-arms that edge only.
        tp.set_function(function::ENABLE | function::NEGATIVE_EDGE);
        tp.set_function(P1_INPUT_BOTH);
        assert_eq!(tp.status() & status::POSITIVE_STORED, 0);
        assert_ne!(tp.status() & status::NEGATIVE_STORED, 0);
        tp.event(home(300, Edge::Positive));
        assert_eq!(tp.value(0, Edge::Positive), 300);
        // Disabling clears the status; the enable's rising edge arms again.
        tp.set_function(0);
        assert_eq!(tp.status(), 0);
        tp.event(home(400, Edge::Positive));
        assert_eq!(tp.value(0, Edge::Positive), 300);
    }

    #[test]
    fn continuous_mode_overwrites_and_toggles() {
        let mut tp = TouchProbe::default();
        tp.set_function(function::ENABLE | function::CONTINUOUS | function::POSITIVE_EDGE);
        tp.event(home(1, Edge::Positive));
        let t1 = tp.status() & status::POSITIVE_TOGGLE;
        tp.event(home(2, Edge::Positive));
        assert_eq!(tp.value(0, Edge::Positive), 2);
        assert_ne!(tp.status() & status::POSITIVE_TOGGLE, t1);
        // The negative edge is not sampled.
        tp.event(home(3, Edge::Negative));
        assert_eq!(tp.status() & status::NEGATIVE_STORED, 0);
    }

    #[test]
    fn probe_2_on_the_zero_impulse_beside_probe_1_on_the_input() {
        let mut tp = TouchProbe::default();
        let p2 = (function::ENABLE | function::SOURCE_ZERO_IMPULSE | function::POSITIVE_EDGE) << 8;
        tp.set_function(function::ENABLE | function::POSITIVE_EDGE | p2);
        tp.event(Event {
            signal: Signal::ZeroImpulse,
            edge: Edge::Positive,
            at: 4096,
        });
        tp.event(home(5000, Edge::Positive));
        assert_eq!(tp.value(1, Edge::Positive), 4096);
        assert_eq!(tp.value(0, Edge::Positive), 5000);
        assert_eq!(
            tp.status(),
            status::ENABLED
                | status::POSITIVE_STORED
                | status::POSITIVE_TOGGLE
                | (status::ENABLED | status::POSITIVE_STORED | status::POSITIVE_TOGGLE) << 8
        );
    }

    #[test]
    fn a_source_the_drive_does_not_have_never_triggers() {
        let mut tp = TouchProbe::default();
        tp.set_function(function::ENABLE | 0b10 << 2 | function::POSITIVE_EDGE);
        tp.event(home(1, Edge::Positive));
        assert_eq!(tp.status(), status::ENABLED);
    }

    #[test]
    fn latched_values_are_the_32_bit_position() {
        let mut tp = TouchProbe::default();
        tp.set_function(P1_INPUT_BOTH);
        tp.event(home(i64::from(i32::MAX) + 1, Edge::Positive));
        assert_eq!(tp.value(0, Edge::Positive), i32::MIN);
    }

    fn home_cam(from: i64, to: i64) -> DriveSwitches {
        DriveSwitches::new(&[SwitchCam {
            input: HOME_INPUT,
            from,
            to,
            normally_closed: false,
        }])
    }

    #[test]
    fn home_edges_are_the_first_count_of_the_new_state() {
        let s = home_cam(100, 199);
        assert_eq!(s.home_edges(0, 99), [None, None]);
        assert_eq!(
            s.home_edges(99, 100),
            [Some(home(100, Edge::Positive)), None]
        );
        assert_eq!(
            s.home_edges(150, 250),
            [None, Some(home(200, Edge::Negative))]
        );
        // Across the whole cam in one step, in the order of travel.
        assert_eq!(
            s.home_edges(0, 1000),
            [
                Some(home(100, Edge::Positive)),
                Some(home(200, Edge::Negative))
            ]
        );
        assert_eq!(
            s.home_edges(1000, 0),
            [
                Some(home(199, Edge::Positive)),
                Some(home(99, Edge::Negative))
            ]
        );
        assert_eq!(s.home_edges(150, 150), [None, None]);
        assert_eq!(s.digital_inputs(150), 1 << HOME_INPUT);
        assert_eq!(s.digital_inputs(200), 0);
    }

    #[test]
    fn index_crossings_both_ways() {
        let e = |at| {
            Some(Event {
                signal: Signal::ZeroImpulse,
                edge: Edge::Positive,
                at,
            })
        };
        assert_eq!(index_crossing(0, 5000, 100, 4096), e(100));
        assert_eq!(index_crossing(100, 5000, 100, 4096), e(4196));
        assert_eq!(index_crossing(101, 4195, 100, 4096), None);
        assert_eq!(index_crossing(5000, 0, 100, 4096), e(4196));
        assert_eq!(index_crossing(4196, 0, 100, 4096), e(100));
        assert_eq!(index_crossing(-1, -5000, 100, 4096), e(-3996));
        assert_eq!(index_crossing(7, 7, 100, 4096), None);
    }
}
