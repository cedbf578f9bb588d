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
//! value in continuous mode too. Bits 2–3 = 11b (reserved) never trigger. The zero
//! impulse is a mark, not a level: it latches on the positive-edge sample only.
//!
//! Source 10b takes the probe's source from 0x60D0 (sub 1 probe 1, sub 2 probe 2;
//! ETG.6010). The simulated drive has the values [`source::ALLOWED`]: its probe inputs 1
//! and 2 (both the home switch), the hardware zero impulse, and — manufacturer-specific,
//! negative as ETG.6010 reserves them — its negative and positive limit switch inputs, so
//! that a master homing on a limit switch's edge latches it; 3, 4 (inputs it does not
//! have) and 6 (a software zero impulse it does not make) are refused (abort 0x06090030).

use crate::plant::switches::SwitchCam;

/// 0x60D0 values the simulated drive has.
pub mod source {
    use gantry_drives::cia402::objects::touch_probe_source as etg;

    /// Touch probe input 1 (the home switch).
    pub const INPUT_1: i16 = etg::PROBE_INPUT_1;
    /// Touch probe input 2 (the home switch too).
    pub const INPUT_2: i16 = etg::PROBE_INPUT_2;
    /// The encoder's hardware zero impulse.
    pub const ZERO_IMPULSE: i16 = etg::HARDWARE_ZERO_IMPULSE;
    /// Manufacturer-specific: the negative limit switch input (0x60FD bit 0).
    pub const NEGATIVE_LIMIT: i16 = -1;
    /// Manufacturer-specific: the positive limit switch input (0x60FD bit 1).
    pub const POSITIVE_LIMIT: i16 = -2;
    /// Every value 0x60D0:1 and :2 take.
    pub const ALLOWED: [i64; 5] = [
        NEGATIVE_LIMIT as i64,
        POSITIVE_LIMIT as i64,
        INPUT_1 as i64,
        INPUT_2 as i64,
        ZERO_IMPULSE as i64,
    ];
    /// Power-up values of 0x60D0:1 and :2: each probe on its own input.
    pub const DEFAULT: [i16; 2] = [INPUT_1, INPUT_2];
}

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
    /// Source: as 0x60D0 says (sub 1 for probe 1, sub 2 for probe 2).
    pub const SOURCE_60D0: u16 = 0b10 << 2;
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
    /// The negative limit switch input.
    NegativeLimit,
    /// The positive limit switch input.
    PositiveLimit,
}

impl Signal {
    /// The signal a 0x60D0 value selects.
    fn of_source(value: i16) -> Option<Self> {
        match value {
            source::INPUT_1 | source::INPUT_2 => Some(Signal::Input),
            source::ZERO_IMPULSE => Some(Signal::ZeroImpulse),
            source::NEGATIVE_LIMIT => Some(Signal::NegativeLimit),
            source::POSITIVE_LIMIT => Some(Signal::PositiveLimit),
            _ => None,
        }
    }
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

    /// An event happened: every probe armed for it latches its position; `sources` is
    /// 0x60D0:1 and :2 (for a probe whose source bits say 10b).
    pub fn event(&mut self, e: Event, sources: [i16; 2]) {
        for n in 0..PROBES {
            let shift = 8 * n;
            let f = (self.function >> shift) & 0xFF;
            if f & function::ENABLE == 0 {
                continue;
            }
            let signal = match f & function::SOURCE_MASK {
                0 => Some(Signal::Input),
                function::SOURCE_ZERO_IMPULSE => Some(Signal::ZeroImpulse),
                function::SOURCE_60D0 => sources.get(n).copied().and_then(Signal::of_source),
                _ => None,
            };
            // The zero impulse is a mark: positive edge only.
            let wanted = signal == Some(e.signal)
                && (e.signal != Signal::ZeroImpulse || e.edge == Edge::Positive);
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
        self.edges(HOME_INPUT, Signal::Input, from, to)
    }

    /// The edges of the cam on 0x60FD bit `input` on the way from count `from` to count
    /// `to`, as events of `signal`, in the order of travel.
    pub fn edges(&self, input: u8, signal: Signal, from: i64, to: i64) -> [Option<Event>; 2] {
        let mut out = [None; 2];
        let Some(Some(cam)) = self.cams.get(usize::from(input)) else {
            return out;
        };
        let event = |edge, at| Some(Event { signal, edge, at });
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
        tp.event(home(100, Edge::Positive), source::DEFAULT);
        tp.event(home(200, Edge::Positive), source::DEFAULT);
        assert_eq!(tp.value(0, Edge::Positive), 100);
        assert_eq!(
            tp.status(),
            status::ENABLED | status::POSITIVE_STORED | status::POSITIVE_TOGGLE
        );
        tp.event(home(150, Edge::Negative), source::DEFAULT);
        assert_eq!(tp.value(0, Edge::Negative), 150);
        // Clearing the positive sample bit re-arms that edge only.
        tp.set_function(function::ENABLE | function::NEGATIVE_EDGE);
        tp.set_function(P1_INPUT_BOTH);
        assert_eq!(tp.status() & status::POSITIVE_STORED, 0);
        assert_ne!(tp.status() & status::NEGATIVE_STORED, 0);
        tp.event(home(300, Edge::Positive), source::DEFAULT);
        assert_eq!(tp.value(0, Edge::Positive), 300);
        // Disabling clears the status; the enable's rising edge arms again.
        tp.set_function(0);
        assert_eq!(tp.status(), 0);
        tp.event(home(400, Edge::Positive), source::DEFAULT);
        assert_eq!(tp.value(0, Edge::Positive), 300);
    }

    #[test]
    fn continuous_mode_overwrites_and_toggles() {
        let mut tp = TouchProbe::default();
        tp.set_function(function::ENABLE | function::CONTINUOUS | function::POSITIVE_EDGE);
        tp.event(home(1, Edge::Positive), source::DEFAULT);
        let t1 = tp.status() & status::POSITIVE_TOGGLE;
        tp.event(home(2, Edge::Positive), source::DEFAULT);
        assert_eq!(tp.value(0, Edge::Positive), 2);
        assert_ne!(tp.status() & status::POSITIVE_TOGGLE, t1);
        // The negative edge is not sampled.
        tp.event(home(3, Edge::Negative), source::DEFAULT);
        assert_eq!(tp.status() & status::NEGATIVE_STORED, 0);
    }

    #[test]
    fn probe_2_on_the_zero_impulse_beside_probe_1_on_the_input() {
        let mut tp = TouchProbe::default();
        let p2 = (function::ENABLE | function::SOURCE_ZERO_IMPULSE | function::POSITIVE_EDGE) << 8;
        tp.set_function(function::ENABLE | function::POSITIVE_EDGE | p2);
        tp.event(
            Event {
                signal: Signal::ZeroImpulse,
                edge: Edge::Positive,
                at: 4096,
            },
            source::DEFAULT,
        );
        tp.event(home(5000, Edge::Positive), source::DEFAULT);
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
        // Bits 2–3 = 11b: reserved.
        tp.set_function(function::ENABLE | 0b11 << 2 | function::POSITIVE_EDGE);
        tp.event(home(1, Edge::Positive), source::DEFAULT);
        assert_eq!(tp.status(), status::ENABLED);
        // 10b with a 0x60D0 value it has not (0: reserved).
        tp.set_function(0);
        tp.set_function(function::ENABLE | function::SOURCE_60D0 | function::POSITIVE_EDGE);
        tp.event(home(1, Edge::Positive), [0, 0]);
        assert_eq!(tp.status(), status::ENABLED);
    }

    /// 0x60B8 source 10b: probe 1 on 0x60D0:1 = the negative limit, probe 2 on 0x60D0:2
    /// = the positive limit; each latches its own switch's edges and nothing else.
    #[test]
    fn the_source_in_0x60d0_routes_a_probe_to_a_limit_switch() {
        let mut tp = TouchProbe::default();
        let both = function::ENABLE
            | function::SOURCE_60D0
            | function::POSITIVE_EDGE
            | function::NEGATIVE_EDGE;
        tp.set_function(both | both << 8);
        let sources = [source::NEGATIVE_LIMIT, source::POSITIVE_LIMIT];
        let ev = |signal, edge, at| Event { signal, edge, at };
        tp.event(home(10, Edge::Positive), sources);
        tp.event(ev(Signal::ZeroImpulse, Edge::Positive, 20), sources);
        assert_eq!(tp.status(), status::ENABLED | status::ENABLED << 8);
        tp.event(ev(Signal::NegativeLimit, Edge::Positive, -1000), sources);
        tp.event(ev(Signal::PositiveLimit, Edge::Negative, 9000), sources);
        assert_eq!(tp.value(0, Edge::Positive), -1000);
        assert_eq!(tp.value(1, Edge::Negative), 9000);
        assert_eq!(tp.value(0, Edge::Negative), 0);
        assert_eq!(tp.value(1, Edge::Positive), 0);
        // 0x60D0 = 5: the zero impulse, as bits 2–3 = 01b would.
        tp.set_function(0);
        tp.set_function(both);
        tp.event(
            ev(Signal::ZeroImpulse, Edge::Positive, 4096),
            [source::ZERO_IMPULSE, 2],
        );
        assert_eq!(tp.value(0, Edge::Positive), 4096);
    }

    #[test]
    fn limit_cams_give_edges_of_their_signal() {
        let s = DriveSwitches::new(&[SwitchCam {
            input: 1,
            from: 5000,
            to: i64::MAX,
            normally_closed: false,
        }]);
        assert_eq!(s.home_edges(0, 6000), [None, None]);
        let [on, off] = s.edges(1, Signal::PositiveLimit, 4000, 6000);
        assert_eq!(
            on,
            Some(Event {
                signal: Signal::PositiveLimit,
                edge: Edge::Positive,
                at: 5000
            })
        );
        assert_eq!(off, None);
        let [_, off] = s.edges(1, Signal::PositiveLimit, 6000, 4000);
        assert_eq!(off.map(|e| (e.edge, e.at)), Some((Edge::Negative, 4999)));
    }

    #[test]
    fn latched_values_are_the_32_bit_position() {
        let mut tp = TouchProbe::default();
        tp.set_function(P1_INPUT_BOTH);
        tp.event(
            home(i64::from(i32::MAX) + 1, Edge::Positive),
            source::DEFAULT,
        );
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
