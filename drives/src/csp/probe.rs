//! The master's side of a drive's touch probe (CiA 402 0x60B8–0x60BC) and digital inputs
//! (0x60FD): arm the probes, turn each value the drive latched into one "new latch" for
//! exactly one cycle, and read the limit and home switches with their polarity.
//!
//! The probes run in first-event mode, which every drive with a touch probe has (the
//! continuous mode's "new value" toggle bits are not in the profile): probe 1 on its input
//! (wired to the home switch), both edges; probe 2 on the encoder's zero impulse, positive
//! edge. When an edge is stored the channel reports it, clears that edge's sample-enable
//! bit until the drive has cleared its stored bit, then sets it again: re-armed two cycles
//! after a latch. An edge within those two cycles is not latched — homing takes one edge
//! per phase, far apart. A drive whose probe is not enabled (after power-up or a reset)
//! sees the enable bit's rising edge: the function is sent as 0 for one cycle, then armed;
//! the channel then waits [`ARM_WAIT_CYCLES`] for the status to show it (outputs reach a
//! drive and its status comes back a few cycles later) before it tries again — whatever
//! the status says meanwhile: a status without the enable may still be the echo of the 0.
//!
//! Homing on a limit switch's edge ([`ProbeTarget`]): a probe's source bits 2–3 = 10b
//! take the source from 0x60D0 (CiA 402-2 / ETG.6010; sub 1 for probe 1, sub 2 for probe
//! 2), which the bring-up set to the drive's code for its negative (sub 1) and positive
//! (sub 2) limit switch input — manufacturer-specific values (ETG.6010 gives 1–4 the
//! probe inputs and 5/6 the zero impulse; negative values are the manufacturer's). The
//! negative limit takes probe 1 (0x60BA/0x60BB, probe 2 stays on the index pulse), the
//! positive one probe 2 (0x60BC/0x60BD) with probe 1 on the index pulse meanwhile (bits
//! 2–3 = 01b, the zero impulse, which either probe takes; 0x60BA then holds the index). A change of target disables both probes until
//! the drive shows them disabled (so no value stored under the old source is taken for a
//! new one), then arms them afresh.

use crate::cia402::objects::digital_inputs;

/// Function bits (probe 2 at bit 8).
const ENABLE: u16 = 1 << 0;
const ZERO_IMPULSE: u16 = 0b01 << 2;
/// Source bits 2–3 = 10b: the source in 0x60D0 (sub 1 probe 1, sub 2 probe 2).
const SOURCE_60D0: u16 = 0b10 << 2;
const POSITIVE: u16 = 1 << 4;
const NEGATIVE: u16 = 1 << 5;
/// Status bits (probe 2 at bit 8).
const ENABLED: u16 = 1 << 0;
const POSITIVE_STORED: u16 = 1 << 1;
const NEGATIVE_STORED: u16 = 1 << 2;

/// 0x60B8 as armed: probe 1 on its input, both edges; probe 2 on the zero impulse,
/// positive edge; first event each.
pub const PROBE_FUNCTION: u16 =
    ENABLE | POSITIVE | NEGATIVE | (ENABLE | ZERO_IMPULSE | POSITIVE) << 8;

/// 0x60B8 with probe 1 on 0x60D0:01 (the negative limit switch), both edges; probe 2 on
/// the zero impulse.
pub const PROBE_FUNCTION_NEGATIVE_LIMIT: u16 =
    ENABLE | SOURCE_60D0 | POSITIVE | NEGATIVE | (ENABLE | ZERO_IMPULSE | POSITIVE) << 8;

/// 0x60B8 with probe 1 on the zero impulse, positive edge; probe 2 on 0x60D0:02 (the
/// positive limit switch), both edges.
pub const PROBE_FUNCTION_POSITIVE_LIMIT: u16 =
    ENABLE | ZERO_IMPULSE | POSITIVE | (ENABLE | SOURCE_60D0 | POSITIVE | NEGATIVE) << 8;

/// Cycles an arming may take to show in the status before it is tried again.
pub const ARM_WAIT_CYCLES: u8 = 16;

/// Which switch's edges the channel reports as the rising and falling latches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ProbeTarget {
    /// Probe 1's input (the home switch); probe 2 on the index pulse.
    #[default]
    Reference,
    /// The negative limit switch (probe 1 on 0x60D0:01); probe 2 on the index pulse.
    NegativeLimit,
    /// The positive limit switch (probe 2 on 0x60D0:02); probe 1 on the index pulse.
    PositiveLimit,
}

impl ProbeTarget {
    /// 0x60B8 armed for this target.
    pub const fn function(self) -> u16 {
        match self {
            ProbeTarget::Reference => PROBE_FUNCTION,
            ProbeTarget::NegativeLimit => PROBE_FUNCTION_NEGATIVE_LIMIT,
            ProbeTarget::PositiveLimit => PROBE_FUNCTION_POSITIVE_LIMIT,
        }
    }

    /// The channels this target reports.
    const fn channels(self) -> [Option<Channel>; 3] {
        const P1_RISING: Channel = Channel::new(POSITIVE, 0, Latched::Rising);
        const P1_FALLING: Channel = Channel::new(NEGATIVE, 1, Latched::Falling);
        const P2_INDEX: Channel = Channel::new(POSITIVE << 8, 2, Latched::Index);
        match self {
            ProbeTarget::Reference | ProbeTarget::NegativeLimit => {
                [Some(P1_RISING), Some(P1_FALLING), Some(P2_INDEX)]
            }
            ProbeTarget::PositiveLimit => [
                Some(Channel::new(POSITIVE << 8, 2, Latched::Rising)),
                Some(Channel::new(NEGATIVE << 8, 3, Latched::Falling)),
                Some(Channel::new(POSITIVE, 0, Latched::Index)),
            ],
        }
    }
}

/// What a channel's latch means to the axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Latched {
    /// The switch became active.
    Rising,
    /// The switch became inactive.
    Falling,
    /// The index pulse.
    Index,
}

/// One edge of one probe the channel latches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Channel {
    /// Its sample-enable bit in 0x60B8.
    sample: u16,
    /// Its stored bit in 0x60B9.
    stored: u16,
    /// Which of 0x60BA, 0x60BB, 0x60BC, 0x60BD holds its value.
    value: usize,
    latched: Latched,
}

// The status has the function's edge bits three places lower.
const _: () = assert!(POSITIVE >> 3 == POSITIVE_STORED && NEGATIVE >> 3 == NEGATIVE_STORED);

impl Channel {
    const fn new(sample: u16, value: usize, latched: Latched) -> Self {
        Self {
            sample,
            // Sample bit 4 (5) ↔ stored bit 1 (2), probe 2 eight bits up.
            stored: sample >> 3,
            value,
            latched,
        }
    }
}

/// Values the drive latched this cycle (32-bit counts), new ones only.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NewLatches {
    /// The switch the probe watches became active here.
    pub rising: Option<i32>,
    /// The switch the probe watches became inactive here.
    pub falling: Option<i32>,
    /// The index pulse passed here.
    pub index: Option<i32>,
}

/// What the drive's probe objects say this cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProbeInputs {
    /// 0x60B9.
    pub status: u16,
    /// 0x60BA, 0x60BB, 0x60BC, 0x60BD (`None` where not mapped).
    pub values: [Option<i32>; 4],
}

/// The arming of one drive's probes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProbeArming {
    /// Per channel: reported, its sample bit cleared until the drive clears the stored bit.
    clearing: [bool; 3],
    /// The function sent last.
    function: u16,
    /// Cycles left for an arming to show in the status.
    waiting: u8,
    /// What the probes are armed for.
    target: ProbeTarget,
    /// What the axis wants them on.
    wanted: ProbeTarget,
    /// A change of target: disabled, waiting for the drive to show it.
    switching: bool,
}

impl ProbeArming {
    /// 0x60B8 for this cycle's outputs.
    pub fn function(&self) -> u16 {
        self.function
    }

    /// What the probes should latch from the next update on.
    pub fn set_target(&mut self, target: ProbeTarget) {
        self.wanted = target;
    }

    /// What the probes are armed for (or being switched to).
    pub fn target(&self) -> ProbeTarget {
        self.target
    }

    /// Takes the drive's probe objects; returns the new latches and sets the function to
    /// send.
    pub fn update(&mut self, inputs: &ProbeInputs) -> NewLatches {
        let st = inputs.status;
        let mut new = NewLatches::default();
        let both = ENABLED | ENABLED << 8;
        if self.wanted != self.target {
            // Disable both; arm for the new target once the drive shows them off.
            self.target = self.wanted;
            self.switching = true;
            self.clearing = [false; 3];
            self.function = 0;
            self.waiting = ARM_WAIT_CYCLES;
            return new;
        }
        if self.switching {
            if st & both != 0 && self.waiting > 0 {
                self.waiting -= 1;
                return new;
            }
            // Off (or the drive never shows it: arm anyway after the wait).
            self.switching = false;
            self.waiting = 0;
        }
        let base = self.target.function();
        if self.function == 0 {
            // 0 went out last cycle (power-up, a change of target, or so that the enable
            // gets a rising edge): arm now, whatever this cycle's status says — it answers
            // what was sent cycles ago, and an "enabled" there is not this arming.
            self.clearing = [false; 3];
            self.function = base;
            self.waiting = ARM_WAIT_CYCLES;
            return new;
        }
        if st & both != both {
            // Not armed (power-up, reset): the enable's rising edge arms it — once the
            // arming's wait is over (until then the status may still be on its way).
            self.clearing = [false; 3];
            if self.waiting > 0 {
                self.waiting -= 1;
            } else {
                self.function = 0;
            }
            return new;
        }
        // An arming's wait runs out whatever the status says meanwhile: a status without
        // the enable right after one with it may be the echo of the 0 sent before the
        // arming (the status comes back cycles after the function went out); taken for a
        // reset, it would disarm the probe again and again.
        self.waiting = self.waiting.saturating_sub(1);
        let mut f = base;
        for (i, ch) in self.target.channels().into_iter().enumerate() {
            let (Some(ch), Some(clearing)) = (ch, self.clearing.get_mut(i)) else {
                continue;
            };
            if *clearing {
                if st & ch.stored == 0 {
                    // The drive took the cleared sample bit: arm the edge again.
                    *clearing = false;
                } else {
                    f &= !ch.sample;
                }
            } else if st & ch.stored != 0 {
                let value = inputs.values.get(ch.value).copied().flatten();
                match ch.latched {
                    Latched::Rising => new.rising = value,
                    Latched::Falling => new.falling = value,
                    Latched::Index => new.index = value,
                }
                *clearing = true;
                f &= !ch.sample;
            }
        }
        self.function = f;
        new
    }
}

/// How the switches' 0x60FD bits are read: which are wired, and which read inverted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SwitchWiring {
    /// 0x60FD bits in use (negative limit, positive limit, home).
    pub used: u32,
    /// Bits whose level is inverted (a drive that reports the contact's level, wired
    /// normally closed).
    pub inverted: u32,
}

/// The switches a drive reports, active or not.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveSwitches {
    /// Negative limit switch active.
    pub negative_limit: bool,
    /// Positive limit switch active.
    pub positive_limit: bool,
    /// Home switch active.
    pub home: bool,
}

impl SwitchWiring {
    /// The switches from 0x60FD.
    pub fn read(&self, digital_inputs: u32) -> DriveSwitches {
        let active = (digital_inputs ^ self.inverted) & self.used;
        DriveSwitches {
            negative_limit: active & digital_inputs::NEGATIVE_LIMIT != 0,
            positive_limit: active & digital_inputs::POSITIVE_LIMIT != 0,
            home: active & digital_inputs::HOME_SWITCH != 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inputs(status: u16, values: [i32; 3]) -> ProbeInputs {
        let [a, b, c] = values;
        ProbeInputs {
            status,
            values: [Some(a), Some(b), Some(c), Some(0)],
        }
    }

    #[test]
    fn channels_have_their_stored_bits() {
        let [r, f, i] = ProbeTarget::Reference.channels().map(Option::unwrap);
        assert_eq!(
            (r.sample, r.stored, r.value),
            (POSITIVE, POSITIVE_STORED, 0)
        );
        assert_eq!(
            (f.sample, f.stored, f.value),
            (NEGATIVE, NEGATIVE_STORED, 1)
        );
        assert_eq!(
            (i.sample, i.stored, i.value),
            (POSITIVE << 8, POSITIVE_STORED << 8, 2)
        );
        let [r, f, i] = ProbeTarget::PositiveLimit.channels();
        assert_eq!(
            r.map(|c| (c.stored, c.value)),
            Some((POSITIVE_STORED << 8, 2))
        );
        assert_eq!(
            f.map(|c| (c.stored, c.value)),
            Some((NEGATIVE_STORED << 8, 3))
        );
        assert_eq!(i.map(|c| (c.stored, c.value)), Some((POSITIVE_STORED, 0)));
        // 0x60B8 per target (CiA 402-2: bits 2–3 = 10b the source in 0x60D0).
        assert_eq!(PROBE_FUNCTION, 0x1531);
        assert_eq!(PROBE_FUNCTION_NEGATIVE_LIMIT, 0x1539);
        assert_eq!(PROBE_FUNCTION_POSITIVE_LIMIT, 0x3915);
    }

    /// Homing on the positive limit: both probes off until the drive shows it, then
    /// armed with probe 2 on 0x60D0:02 and probe 1 on the index pulse; probe 2's edges
    /// (0x60BC/0x60BD) are the rising and falling latches, probe 1's positive edge
    /// (0x60BA) the index; a value stored before the change is never reported.
    #[test]
    fn a_change_of_target_disarms_first_then_reports_the_new_source() {
        let mut p = ProbeArming::default();
        p.update(&inputs(0, [0; 3]));
        p.update(&inputs(ARMED, [0; 3]));
        assert_eq!(p.function(), PROBE_FUNCTION);
        p.set_target(ProbeTarget::PositiveLimit);
        // A home edge stored under the old arming, still shown: not reported.
        let stale = ARMED | POSITIVE_STORED | POSITIVE_STORED << 8;
        assert_eq!(p.update(&inputs(stale, [11, 0, 22])), NewLatches::default());
        assert_eq!(p.function(), 0);
        assert_eq!(p.update(&inputs(stale, [11, 0, 22])), NewLatches::default());
        assert_eq!(p.function(), 0, "off until the drive shows it");
        // Off: armed for the positive limit.
        assert_eq!(p.update(&inputs(0, [11, 0, 22])), NewLatches::default());
        assert_eq!(p.function(), PROBE_FUNCTION_POSITIVE_LIMIT);
        p.update(&inputs(ARMED, [11, 0, 22]));
        // Probe 2's negative edge (0x60BD) is the falling latch.
        let mut i = inputs(ARMED | NEGATIVE_STORED << 8, [11, 0, 22]);
        i.values[3] = Some(-500);
        let new = p.update(&i);
        assert_eq!(
            new,
            NewLatches {
                rising: None,
                falling: Some(-500),
                index: None
            }
        );
        assert_eq!(
            p.function(),
            PROBE_FUNCTION_POSITIVE_LIMIT & !(NEGATIVE << 8)
        );
        // Probe 1's positive edge is now the index pulse.
        let new = p.update(&inputs(
            ARMED | POSITIVE_STORED | NEGATIVE_STORED << 8,
            [9, 0, 0],
        ));
        assert_eq!(
            new,
            NewLatches {
                index: Some(9),
                ..NewLatches::default()
            }
        );
        // Back to the reference: off, then armed as before.
        p.set_target(ProbeTarget::Reference);
        p.update(&inputs(ARMED, [0; 3]));
        assert_eq!(p.function(), 0);
        p.update(&inputs(0, [0; 3]));
        assert_eq!(p.function(), PROBE_FUNCTION);
    }

    const ARMED: u16 = ENABLED | ENABLED << 8;

    #[test]
    fn arms_reports_each_latch_once_and_rearms() {
        let mut p = ProbeArming::default();
        // Power-up: not enabled; the function goes out and stays while the status may
        // still be on its way; not enabled after that: 0 for one cycle so that the next
        // one is a rising edge, then armed again.
        assert_eq!(p.update(&inputs(0, [0; 3])), NewLatches::default());
        assert_eq!(p.function(), PROBE_FUNCTION);
        for _ in 0..ARM_WAIT_CYCLES {
            p.update(&inputs(0, [0; 3]));
            assert_eq!(p.function(), PROBE_FUNCTION);
        }
        p.update(&inputs(0, [0; 3]));
        assert_eq!(p.function(), 0);
        p.update(&inputs(0, [0; 3]));
        assert_eq!(p.function(), PROBE_FUNCTION);
        // Armed, nothing stored.
        assert_eq!(p.update(&inputs(ARMED, [0; 3])), NewLatches::default());
        assert_eq!(p.function(), PROBE_FUNCTION);
        // The rising edge is stored: reported once, its sample bit cleared.
        let st = ARMED | POSITIVE_STORED;
        let new = p.update(&inputs(st, [1234, 0, 0]));
        assert_eq!(new.rising, Some(1234));
        assert_eq!(p.function(), PROBE_FUNCTION & !POSITIVE);
        // Still stored (the drive has not seen the cleared bit): not again.
        assert_eq!(p.update(&inputs(st, [1234, 0, 0])), NewLatches::default());
        assert_eq!(p.function(), PROBE_FUNCTION & !POSITIVE);
        // Cleared by the drive: armed again.
        p.update(&inputs(ARMED, [1234, 0, 0]));
        assert_eq!(p.function(), PROBE_FUNCTION);
        // Index and falling edge in one cycle.
        let st = ARMED | NEGATIVE_STORED | POSITIVE_STORED << 8;
        let new = p.update(&inputs(st, [1234, 2000, 4096]));
        assert_eq!(
            new,
            NewLatches {
                rising: None,
                falling: Some(2000),
                index: Some(4096)
            }
        );
        assert_eq!(p.function(), PROBE_FUNCTION & !NEGATIVE & !(POSITIVE << 8));
    }

    #[test]
    fn a_drive_that_lost_its_arming_is_armed_again() {
        let mut p = ProbeArming::default();
        p.update(&inputs(0, [0; 3]));
        p.update(&inputs(ARMED | POSITIVE_STORED, [5, 0, 0]));
        // Within the arming's wait a status without the enable may still be the echo of
        // what was sent before the arming: the function stays.
        for _ in 1..ARM_WAIT_CYCLES {
            p.update(&inputs(0, [0; 3]));
            assert_ne!(p.function() & ENABLE, 0, "armed while the wait runs");
        }
        // The drive reset: enable bits gone after the wait. 0 for one cycle, then the
        // enable's rising edge.
        p.update(&inputs(0, [0; 3]));
        assert_eq!(p.function(), 0, "enable low for one cycle");
        p.update(&inputs(0, [0; 3]));
        assert_eq!(p.function(), PROBE_FUNCTION);
        // Armed afresh: a stored edge is new.
        let new = p.update(&inputs(ARMED | POSITIVE_STORED, [7, 0, 0]));
        assert_eq!(new.rising, Some(7));
    }

    /// A drive whose status answers the function `latency` cycles after the master sent
    /// it (outputs reach the drive and its status comes back later: 2 to 3 cycles on
    /// EtherCAT with DC, by the frame's phase to SYNC0). Whatever is in flight when the
    /// channel starts — an arming and a disarming in either order — it settles armed and
    /// stays so: a status without the enable that is only the echo of an earlier 0 must not
    /// disarm the probe again. (It did: with a 0 in flight behind an arming, each stale
    /// "not enabled" after an "enabled" sent 0 again, a period-3 oscillation during which
    /// the drive latched nothing — homing found a later index pulse, seen by the homing
    /// matrix on the simulated servo over EtherCAT.)
    #[test]
    fn settles_armed_whatever_the_status_latency_and_what_is_in_flight() {
        for latency in 1..=4usize {
            for pattern in 0..(1u32 << latency) {
                for glitch in [false, true] {
                    let what = format!("latency {latency}, in flight {pattern:b}, glitch {glitch}");
                    let mut p = ProbeArming::default();
                    let sent = |i: usize| {
                        if pattern >> i & 1 == 1 {
                            PROBE_FUNCTION
                        } else {
                            0
                        }
                    };
                    // What the master sent before, oldest first.
                    let mut in_flight: std::collections::VecDeque<u16> =
                        (0..latency).map(sent).collect();
                    // The drive: the enable's rising edge arms a probe, a 0 disarms it.
                    let (mut last, mut status) = (0u16, 0u16);
                    let mut zeros_late = 0;
                    let cycles = 300;
                    for cycle in 0..cycles {
                        if glitch && cycle == 100 {
                            // Armed and settled, then the drive resets (its probes are
                            // disarmed) with this in flight.
                            assert_eq!(status, ARMED, "{what}: armed before the glitch");
                            in_flight = (0..latency).map(sent).collect();
                            (last, status) = (0, 0);
                        }
                        p.update(&inputs(status, [0; 3]));
                        in_flight.push_back(p.function());
                        let f = in_flight.pop_front().unwrap_or(0);
                        status = match (f & ENABLE != 0, last & ENABLE != 0) {
                            (false, _) => 0,
                            (true, false) => ARMED,
                            (true, true) => status,
                        };
                        last = f;
                        if cycle >= cycles - 100 && p.function() == 0 {
                            zeros_late += 1;
                        }
                    }
                    assert_eq!((zeros_late, status), (0, ARMED), "{what}: still disarming");
                }
            }
        }
    }

    #[test]
    fn switches_with_polarity() {
        let w = SwitchWiring {
            used: digital_inputs::NEGATIVE_LIMIT | digital_inputs::HOME_SWITCH,
            inverted: digital_inputs::NEGATIVE_LIMIT,
        };
        assert_eq!(
            w.read(0),
            DriveSwitches {
                negative_limit: true,
                positive_limit: false,
                home: false
            }
        );
        // The positive limit bit is not wired: ignored.
        assert_eq!(
            w.read(0b111),
            DriveSwitches {
                negative_limit: false,
                positive_limit: false,
                home: true
            }
        );
    }
}
