//! The motor and load, and the drive's cascaded loops that move them: a PI velocity loop
//! over a current loop with a torque (current) limit, the load an inertia with Coulomb and
//! viscous friction. One [`Motor::substep`] is one period of the drive's own loop rate; the
//! position loop and the stop ramps (in `super`) give it its velocity command.
//!
//! The motor is a permanent-magnet synchronous motor: its torque is the current vector's
//! amplitude times the sine of the electrical angle between that vector and the rotor's
//! magnets (see [`Commutation`]). In the closed-loop modes the drive puts the vector 90°
//! electrical ahead of where it believes the rotor is, from its encoder count and its
//! commutation offset setting; a setting that misses the motor's true offset by δ yields
//! cos δ of the torque asked for, none at 90°, and beyond 90° torque the wrong way: the
//! velocity loop then drives the motor away from its command, harder the further it gets
//! (positive feedback), until the drive's supervision faults it.
//!
//! Units: positions in encoder counts, velocities in counts/s, torques in N·m, electrical
//! angles in radians.

use core::f64::consts::{FRAC_PI_2, PI};

use super::params::ServoParams;

/// What the power stage is told for one loop period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drive {
    /// Power stage off: no torque, the load coasts against friction.
    Off,
    /// Velocity loop to this velocity (counts/s).
    Velocity(f64),
    /// Torque command straight to the current loop (N·m).
    Torque(f64),
    /// Open loop: the current loop holds a current vector of this amplitude (N·m when
    /// aligned for torque) at this electrical angle of the stator's frame (rad), without
    /// the encoder; the rotor's magnets turn towards it.
    Vector {
        /// Amplitude (N·m of torque it gives at 90° to the rotor).
        current: f64,
        /// Electrical angle in the stator's frame (rad).
        angle: f64,
    },
}

/// Where the motor's magnets are, and where the drive believes they are: the geometry of
/// a permanent-magnet synchronous motor under a field-oriented drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Commutation {
    /// Electrical radians per encoder count: 2π · pole pairs / counts per revolution.
    electrical_per_count: f64,
    /// The motor's true commutation offset (counts): the encoder count at which the
    /// rotor's electrical angle is zero (modulo an electrical revolution).
    offset: f64,
    /// The offset the drive was told (counts).
    setting: f64,
}

impl Commutation {
    /// The commutation of `p`'s motor under a drive whose setting is `setting` (counts).
    pub fn of(p: &ServoParams, setting: i32) -> Self {
        Self {
            electrical_per_count: 2.0 * PI * f64::from(p.pole_pairs)
                / f64::from(p.counts_per_rev.max(1)),
            offset: f64::from(p.commutation_offset),
            setting: f64::from(setting),
        }
    }

    /// The rotor's true electrical angle at load position `position` (rad).
    pub fn rotor(&self, position: f64) -> f64 {
        self.electrical_per_count * (position - self.offset)
    }

    /// The electrical angle the drive computes for the rotor (rad): from its encoder,
    /// which counts whole increments, and its commutation setting.
    pub fn estimate(&self, position: f64) -> f64 {
        self.electrical_per_count * (position.round() - self.setting)
    }

    /// The torque (N·m) a current vector of `current` (N·m when at 90° to the rotor) at
    /// electrical angle `angle` (rad) exerts on the rotor at `position`: the magnets are
    /// pulled towards the vector, with the sine of the angle between them.
    pub fn torque(&self, current: f64, angle: f64, position: f64) -> f64 {
        current * (angle - self.rotor(position)).sin()
    }
}

/// Loop constants for one run of substeps of `h` seconds.
#[derive(Clone, Copy, Debug)]
pub struct Gains {
    /// Substep (s).
    pub h: f64,
    /// Total inertia (kg·m²).
    j: f64,
    /// Radians per count.
    k: f64,
    /// Velocity loop proportional gain (N·m per count/s).
    kv: f64,
    /// Velocity loop integral corner (rad/s): integral time 4/ω_v.
    wi: f64,
    /// Current loop: the fraction of the remaining error closed per substep.
    current: f64,
    coulomb: f64,
    viscous: f64,
}

impl Gains {
    /// The constants of `p` for substeps of `h` seconds.
    pub fn of(p: &ServoParams, h: f64) -> Self {
        let two_pi = 2.0 * core::f64::consts::PI;
        let j = p.inertia();
        let k = two_pi / f64::from(p.counts_per_rev.max(1));
        let wv = two_pi * p.velocity_loop_hz;
        Self {
            h,
            j,
            k,
            kv: j * wv * k,
            wi: wv / 4.0,
            current: 1.0 - (-two_pi * p.current_loop_hz * h).exp(),
            coulomb: p.coulomb_friction_nm,
            viscous: p.viscous_friction_nm_s,
        }
    }

    /// Torque (N·m) that accelerates the total inertia by `a` counts/s².
    pub fn torque_for(&self, a: f64) -> f64 {
        self.j * a * self.k
    }
}

/// The motor, its load and the drive's velocity and current loops.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motor {
    /// Load position (counts).
    pub position: f64,
    /// Load velocity (counts/s).
    pub velocity: f64,
    /// Torque the current loop delivers (N·m), as the drive measures it from the current.
    pub torque: f64,
    /// Velocity loop integrator (N·m).
    integral: f64,
    /// The last substep's torque command was clipped by the limit.
    pub limited: bool,
}

impl Motor {
    /// A motor at rest at `position`.
    pub fn at(position: f64) -> Self {
        Self {
            position,
            ..Self::default()
        }
    }

    /// Clears the velocity loop's integrator (the loop was opened).
    pub fn reset_loops(&mut self) {
        self.integral = 0.0;
    }

    /// One loop period: the velocity loop makes a torque command, the current loop follows
    /// it within `limit` (N·m) along the electrical angle the drive commutates to (90°
    /// ahead of the rotor as the drive estimates it; in [`Drive::Vector`] the angle
    /// given), and the motor turns that current into torque by its true angle to the rotor
    /// (`commutation`), against the load's inertia and friction.
    pub fn substep(&mut self, g: &Gains, drive: Drive, limit: f64, commutation: &Commutation) {
        let limit = limit.max(0.0);
        let mut angle = None;
        let command = match drive {
            Drive::Off => {
                self.integral = 0.0;
                self.torque = 0.0;
                self.limited = false;
                None
            }
            Drive::Torque(t) => {
                self.integral = 0.0;
                Some(t)
            }
            Drive::Vector { current, angle: a } => {
                self.integral = 0.0;
                angle = Some(a);
                Some(current)
            }
            Drive::Velocity(v) => {
                let e = v - self.velocity;
                let p = g.kv * e;
                let unclipped = p + self.integral;
                // Anti-windup: integrate only while the output is free or the error
                // pulls it back inside the limit.
                if unclipped.abs() < limit || unclipped.signum() != e.signum() {
                    self.integral += g.kv * g.wi * e * g.h;
                    self.integral = self.integral.clamp(-limit, limit);
                }
                Some(p + self.integral)
            }
        };
        if let Some(c) = command {
            self.limited = c.abs() > limit;
            let c = c.clamp(-limit, limit);
            self.torque += (c - self.torque) * g.current;
        }
        let vector = angle.unwrap_or_else(|| commutation.estimate(self.position) + FRAC_PI_2);
        let tm = commutation.torque(self.torque, vector, self.position);
        self.mechanics(g, tm);
    }

    /// The load under motor torque `tm` (N·m) for one substep: Coulomb friction holds it
    /// while |tm| is below the friction torque (stiction equal to Coulomb friction), and
    /// opposes its motion once it moves; viscous friction grows with speed.
    fn mechanics(&mut self, g: &Gains, tm: f64) {
        let w = self.velocity;
        let net = if w == 0.0 {
            if tm.abs() <= g.coulomb {
                return;
            }
            tm - g.coulomb * tm.signum()
        } else {
            tm - g.coulomb * w.signum() - g.viscous * w * g.k
        };
        let a = net / g.j / g.k;
        let mut w1 = w + a * g.h;
        if w != 0.0 && w1.signum() != w.signum() && tm.abs() <= g.coulomb {
            // Friction brought it to rest within the step; it stays.
            w1 = 0.0;
        }
        self.position += 0.5 * (w + w1) * g.h;
        self.velocity = w1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gains() -> (ServoParams, Gains) {
        let p = ServoParams::default();
        (p, Gains::of(&p, 1.0 / p.loop_rate_hz))
    }

    /// A commissioned motor: the drive's setting is the true offset.
    fn aligned(p: &ServoParams) -> Commutation {
        Commutation::of(p, p.commutation_offset)
    }

    #[test]
    fn torque_accelerates_the_inertia_less_friction() {
        let (p, g) = gains();
        let c = aligned(&p);
        let mut m = Motor::default();
        // Rated torque for 10 ms from rest.
        for _ in 0..160 {
            m.substep(&g, Drive::Torque(p.rated_torque_nm), 10.0, &c);
        }
        // a = (T - Tc) / J at low speed (viscous is small): in counts/s².
        let a = (p.rated_torque_nm - p.coulomb_friction_nm) / p.inertia() / g.k;
        // The current loop's lag (80 µs) costs a little of the 10 ms.
        let v = m.velocity;
        assert!(v < a * 0.010 && v > a * 0.0095, "{v} vs {}", a * 0.010);
    }

    #[test]
    fn coulomb_friction_holds_below_breakaway_and_stops_a_coasting_load() {
        let (p, g) = gains();
        let c = aligned(&p);
        let mut m = Motor::default();
        for _ in 0..1600 {
            m.substep(&g, Drive::Torque(0.9 * p.coulomb_friction_nm), 10.0, &c);
        }
        assert_eq!((m.position, m.velocity), (0.0, 0.0), "stiction holds");
        // Coasting from 1000 rpm: friction alone stops it, in about J·ω/(Tc + b·ω).
        let w = 1000.0 / 60.0 * f64::from(p.counts_per_rev);
        m.velocity = w;
        let mut t = 0.0;
        while m.velocity != 0.0 && t < 10.0 {
            m.substep(&g, Drive::Off, 10.0, &c);
            t += g.h;
        }
        let w_rad = w * g.k;
        let bound = p.inertia() * w_rad / p.coulomb_friction_nm;
        assert!(
            t > 0.0 && t < bound,
            "stopped after {t} s (Coulomb alone: {bound} s)"
        );
        assert!(m.position > 0.0);
    }

    #[test]
    fn the_torque_limit_caps_the_velocity_loop() {
        let (p, g) = gains();
        let c = aligned(&p);
        let mut m = Motor::default();
        m.substep(&g, Drive::Velocity(1e7), p.peak_torque_nm, &c);
        assert!(m.limited);
        for _ in 0..100 {
            m.substep(&g, Drive::Velocity(1e7), p.peak_torque_nm, &c);
        }
        assert!((m.torque - p.peak_torque_nm).abs() < 1e-6, "{}", m.torque);
    }
}
