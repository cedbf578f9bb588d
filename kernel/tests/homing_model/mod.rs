//! A small axis model for the homing tests, run in lockstep with the kernel: the load
//! follows the set position with a first-order lag, carries cams for the limit switches and
//! the reference switch at configured positions, and its encoder gives an index pulse every
//! `index_pitch` units. The touch probe latches the exact load position of every edge of its
//! input and of every index pulse crossed in a cycle, as a drive's touch probe does
//! (CiA 402 0x60BA/0x60BC/0x60BD: latched in hardware, independent of the cycle).
#![allow(dead_code)]

pub mod cases;
pub mod expect;

use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::status::AxisStatus;
use gantry_kernel::axis::{AxisFeedback, AxisSetpoint};
use gantry_kernel::homing::{HomingStatus, Latch, LimitSide, ProbeLatches, SwitchInputs};
use gantry_kernel::profile::{Limits, RampType};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};

/// Cycle time (1 ms).
pub const DT: f64 = 0.001;

/// Which input the touch probe latches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProbeSource {
    /// The reference switch.
    Reference,
    /// A limit switch (homing on a limit switch).
    Limit(LimitSide),
}

/// Where the switches and index pulses are on the load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    /// The negative limit switch is active at and below this position.
    pub negative_limit: f64,
    /// The positive limit switch is active at and above this position.
    pub positive_limit: f64,
    /// The reference cam is active in `[cam.0, cam.1]`.
    pub cam: (f64, f64),
    /// Index pulses at `index_phase + k · index_pitch`.
    pub index_pitch: f64,
    /// Phase of the index pulses.
    pub index_phase: f64,
    /// Modulo period of a rotary axis: cams and pulses repeat every period, positions
    /// and latches are reported within it (the limits are then ±∞).
    pub period: Option<f64>,
}

impl Layout {
    /// Travel ±100, cam [10, 30], index every 7 at 0.3.
    pub const STANDARD: Layout = Layout {
        negative_limit: -100.0,
        positive_limit: 100.0,
        cam: (10.0, 30.0),
        index_pitch: 7.0,
        index_phase: 0.3,
        period: None,
    };

    /// `x` within the period (unchanged without one).
    pub fn wrap(&self, x: f64) -> f64 {
        match self.period {
            Some(p) => x - (x / p).floor() * p,
            None => x,
        }
    }

    /// The switch levels at `x`.
    pub fn levels(&self, x: f64) -> SwitchInputs {
        let x = self.wrap(x);
        SwitchInputs {
            negative_limit: x <= self.negative_limit,
            positive_limit: x >= self.positive_limit,
            reference: x >= self.cam.0 && x <= self.cam.1,
        }
    }

    /// The index pulse closest above `x` (strictly).
    pub fn index_above(&self, x: f64) -> f64 {
        let k = ((x - self.index_phase) / self.index_pitch).floor() + 1.0;
        let p = self.index_phase + k * self.index_pitch;
        if p > x {
            p
        } else {
            p + self.index_pitch
        }
    }

    /// The index pulse closest below `x` (strictly).
    pub fn index_below(&self, x: f64) -> f64 {
        let k = ((x - self.index_phase) / self.index_pitch).ceil() - 1.0;
        let p = self.index_phase + k * self.index_pitch;
        if p < x {
            p
        } else {
            p - self.index_pitch
        }
    }
}

/// The load, its switches, encoder and touch probe.
#[derive(Clone, Copy, Debug)]
pub struct AxisModel {
    /// Where things are.
    pub layout: Layout,
    /// What the probe latches.
    pub probe_source: ProbeSource,
    /// Lag time constant of the load behind the set position (s).
    pub lag_s: f64,
    /// Load position (drive frame).
    pub x: f64,
    /// Load velocity.
    pub v: f64,
    latches: ProbeLatches,
    /// Every edge the probe latched: (position, rising).
    pub edges_latched: usize,
    /// Cycle time (s).
    pub dt: f64,
}

impl AxisModel {
    /// A model at `x0`.
    pub fn new(layout: Layout, x0: f64) -> Self {
        Self {
            layout,
            probe_source: ProbeSource::Reference,
            lag_s: 0.004,
            x: x0,
            v: 0.0,
            latches: ProbeLatches::default(),
            edges_latched: 0,
            dt: DT,
        }
    }

    fn probe_level(&self, x: f64) -> bool {
        let x = self.layout.wrap(x);
        let l = self.layout.levels(x);
        match self.probe_source {
            ProbeSource::Reference => l.reference,
            ProbeSource::Limit(LimitSide::Negative) => l.negative_limit,
            ProbeSource::Limit(LimitSide::Positive) => l.positive_limit,
        }
    }

    /// The probe input's edges: where its level changes.
    fn probe_edges(&self) -> [f64; 2] {
        let l = self.layout;
        match self.probe_source {
            ProbeSource::Reference => [l.cam.0, l.cam.1],
            ProbeSource::Limit(LimitSide::Negative) => [l.negative_limit, l.negative_limit],
            ProbeSource::Limit(LimitSide::Positive) => [l.positive_limit, l.positive_limit],
        }
    }

    /// The feedback of this cycle (the drive is enabled and without fault).
    pub fn feedback(&self) -> AxisFeedback {
        AxisFeedback {
            position: self.layout.wrap(self.x),
            velocity: self.v,
            operation_enabled: true,
            fault: None,
            switches: self.layout.levels(self.x),
            probe: self.latches,
        }
    }

    /// One cycle: the load follows the set position; edges crossed are latched exactly.
    pub fn advance(&mut self, sp: &AxisSetpoint) {
        let x0 = self.x;
        let dt = self.dt;
        let alpha = dt / (self.lag_s + dt);
        let set = match self.layout.period {
            Some(p) => sp.turns as f64 * p + sp.position,
            None => sp.position,
        };
        let x1 = x0 + (set - x0) * alpha;
        self.v = (x1 - x0) / dt;
        self.x = x1;
        let mut latches = ProbeLatches::default();
        let (lo, hi) = if x1 >= x0 { (x0, x1) } else { (x1, x0) };
        // Probe input edges crossed: the level before and after tells rising or falling.
        for e in self.probe_edges() {
            // On a rotary axis the edge repeats every period: its copy nearest below `hi`.
            let e = match self.layout.period {
                Some(p) => e + ((hi - e) / p).floor() * p,
                None => e,
            };
            let crossed = (lo < e && e <= hi) || (lo <= e && e < hi);
            if crossed && self.probe_level(x0) != self.probe_level(x1) {
                let rising = self.probe_level(x1);
                let l = Latch::at(self.layout.wrap(e));
                if rising {
                    latches.rising = l;
                } else {
                    latches.falling = l;
                }
                self.edges_latched += 1;
            }
        }
        // Index pulses crossed: the drive latches the last one crossed (one per cycle).
        let (ph, pitch) = (self.layout.index_phase, self.layout.index_pitch);
        if x1 > x0 {
            let p = ph + ((x1 - ph) / pitch).floor() * pitch;
            if p > x0 {
                latches.index = Latch::at(self.layout.wrap(p));
            }
        } else if x1 < x0 {
            let p = ph + ((x1 - ph) / pitch).ceil() * pitch;
            if p < x0 {
                latches.index = Latch::at(self.layout.wrap(p));
            }
        }
        self.latches = latches;
    }
}

/// A real axis for homing tests: vmax 100, amax/dmax 1000, jmax 20 000, quick-stop 400.
pub fn axis_config() -> AxisConfig {
    let mut c = AxisConfig::new("x", AxisKind::Real);
    c.max = Limits {
        vmax: 100.0,
        amax: 1000.0,
        dmax: 1000.0,
        jmax: 20_000.0,
    };
    c.defaults.speed = 20.0;
    c.defaults.acceleration = 500.0;
    c.defaults.deceleration = 500.0;
    c.defaults.jerk = 10_000.0;
    c.defaults.ramp = RampType::SCurve;
    c.defaults.target_window = 0.05;
    c.quick_stop_deceleration = 400.0;
    c
}

/// One recorded cycle.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Kernel status after the cycle.
    pub status: AxisStatus,
    /// Set values sent to the drive.
    pub setpoint: AxisSetpoint,
    /// Load position after the cycle.
    pub load: f64,
}

/// A kernel with one real axis and its model, enabled.
pub struct Rig {
    /// The kernel.
    pub k: Kernel,
    /// The model.
    pub m: AxisModel,
    /// The last setpoint.
    pub sp: AxisSetpoint,
    /// The model's probe follows the setpoint's routing (on); off: it stays on
    /// `m.probe_source` (a drive whose probe source was never set to the limit switch).
    pub probe_routed: bool,
}

impl Rig {
    /// Kernel and model at `x0`, enabled, cycle time [`DT`].
    pub fn new(cfg: AxisConfig, layout: Layout, x0: f64) -> Self {
        Self::with_cycle(cfg, layout, x0, DT)
    }

    /// Kernel and model at `x0`, enabled, cycle time `dt`.
    pub fn with_cycle(cfg: AxisConfig, layout: Layout, x0: f64, dt: f64) -> Self {
        let mut cfg = cfg;
        cfg.initial_position = x0;
        let k = Kernel::new(dt, vec![cfg]).expect("config");
        let mut m = AxisModel::new(layout, x0);
        m.dt = dt;
        let mut rig = Self {
            k,
            m,
            sp: AxisSetpoint::default(),
            probe_routed: true,
        };
        rig.k
            .command(0, Command::Power(PowerCommand::Enable))
            .expect("enable");
        for _ in 0..3 {
            rig.cycle();
        }
        rig
    }

    /// One lockstep cycle. The model's probe follows the setpoint's routing (a drive
    /// layer that puts the probe on the limit switch the kernel asks for): the limit's
    /// edges are latched only while the kernel asks for them.
    pub fn cycle(&mut self) -> Sample {
        let fb = self.m.feedback();
        let sp = self.k.step(&[fb])[0];
        if self.probe_routed {
            self.m.probe_source = match sp.probe_on_limit {
                Some(side) => ProbeSource::Limit(side),
                None => ProbeSource::Reference,
            };
        }
        self.m.advance(&sp);
        self.sp = sp;
        Sample {
            status: *self.k.axis_status(0).expect("axis"),
            setpoint: sp,
            load: self.m.x,
        }
    }

    /// Runs until `h` is final (at most `max` cycles), recording every cycle into `out`.
    pub fn run_until_final(
        &mut self,
        h: HandleId,
        max: usize,
        out: &mut Vec<Sample>,
    ) -> CommandStatus {
        for _ in 0..max {
            let s = self.cycle();
            out.push(s);
            let st = self.k.command_status(h);
            if st.is_final() {
                return st;
            }
        }
        self.k.command_status(h)
    }

    /// Runs `n` cycles.
    pub fn run(&mut self, n: usize, out: &mut Vec<Sample>) {
        for _ in 0..n {
            let s = self.cycle();
            out.push(s);
        }
    }
}

/// Every sample within speed `v`, acceleration `a` and jerk `j` (set values); the first
/// violation as an error.
pub fn check_limits(samples: &[Sample], v: f64, a: f64, j: f64) -> Result<(), String> {
    let tol = 1e-6;
    for (i, s) in samples.iter().enumerate() {
        let k = s.status.set;
        if k.v.abs() > v * (1.0 + tol) + tol {
            return Err(format!("cycle {i}: |v| = {} > {v}", k.v.abs()));
        }
        if k.a.abs() > a * (1.0 + tol) + tol {
            return Err(format!("cycle {i}: |a| = {} > {a}", k.a.abs()));
        }
        if k.j.abs() > j * (1.0 + tol) + tol {
            return Err(format!("cycle {i}: |j| = {} > {j}", k.j.abs()));
        }
    }
    Ok(())
}

/// The homing status bits only ever turn on, in the order started → switch found →
/// reference found → reference set.
pub fn check_status_sequence(samples: &[Sample]) -> Result<Vec<HomingStatus>, String> {
    let mut seen: Vec<HomingStatus> = Vec::new();
    for s in samples {
        let h = s.status.homing;
        if seen.last() != Some(&h) {
            if let Some(p) = seen.last() {
                let off = |a: bool, b: bool| a && !b;
                if off(p.started, h.started)
                    || off(p.switch_found, h.switch_found)
                    || off(p.reference_found, h.reference_found)
                    || off(p.reference_set, h.reference_set)
                {
                    return Err(format!("a bit went off: {p:?} -> {h:?}"));
                }
            }
            let ordered = (!h.switch_found || h.started)
                && (!h.reference_found || h.switch_found)
                && (!h.reference_set || h.reference_found);
            if !ordered {
                return Err(format!("out of order: {h:?}"));
            }
            seen.push(h);
        }
    }
    Ok(seen)
}
