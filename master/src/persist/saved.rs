//! The running service's saved parameters: what was loaded at start, kept in memory per
//! axis and written to the axis' file ([`Store`]) whenever it changes — the MoveHome
//! parameters of a homing call that carried some (seed 000 §6.3.2: a later call without
//! them uses the saved ones), the step-to-absolute-switch parameters of such a call, which
//! of the two ran last, the dynamics of a move that gave some, an absolute axis' position
//! offset whenever it is homed, the commutation offset commissioning measured.
//!
//! Memory is updated at once; the file writes block (fsync) and are for a thread that
//! may block — the controller's saving thread ([`super::saver`]), never the cycle thread.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use gantry_kernel::axis::Dynamics;
use gantry_kernel::homing::{MoveHome, MoveHomeCall, StepAbsoluteSwitch};
use thiserror::Error;

use super::params::{AxisParams, NotGiven, PositionOffset, PtpParams, ScalingStamp};
use super::store::Store;
use super::PersistError;
use crate::config::{Config, Encoder};
use crate::runtime::protocol::Snapshot;
use crate::service::protocol::{HomeMethod, HomeParams, StepSwitchParams};

/// What one axis remembers.
#[derive(Clone, Debug)]
struct Memory {
    /// The homing parameters a call without any runs with.
    home: MoveHome,
    /// The step-to-absolute-switch run a call without parameters repeats (none yet).
    step: Option<StepAbsoluteSwitch>,
    /// The homing run a call without a method repeats.
    method: HomeMethod,
    /// The axis' default dynamics (step-to-absolute-switch's defaults).
    defaults: Dynamics,
    /// The dynamics a move that leaves them out runs with (those ever given).
    ptp: PtpParams,
    /// The position offset last saved (absolute axes).
    offset: Option<f64>,
    /// The commutation offset saved.
    commutation: Option<i32>,
}

/// What an axis does with its position at start.
#[derive(Clone, Debug, PartialEq)]
pub enum StartPosition {
    /// An incremental encoder: the position counts from where the drive was switched on.
    Incremental,
    /// Restore the saved offset (axis position = drive position + `offset`); `homed`:
    /// mark the axis homed (`homed_at_start`).
    Restore {
        /// Units.
        offset: f64,
        /// Homed at start.
        homed: bool,
    },
    /// An absolute axis whose offset is not restored, and so is not homed: why.
    NotRestored {
        /// Why, for the start-up message.
        reason: String,
        /// Whether the configuration asked for it homed.
        homed_at_start: bool,
    },
}

/// Why a step-to-absolute-switch call has no run.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum StepSwitchNotGiven {
    /// It leaves out a parameter with no default, and the axis has none saved.
    #[error(
        "step-to-absolute-switch homing: no {parameter} given, and axis {axis:?} has none \
         saved (its first step-to-switch homing names direction, switch mode and velocity)"
    )]
    Parameter {
        /// The axis.
        axis: String,
        /// The parameter.
        parameter: &'static str,
    },
    /// No such axis among the saved ones (the controller and the configuration disagree).
    #[error("axis {0} has no saved parameters")]
    NoAxis(usize),
}

/// The service's saved parameters of every axis.
#[derive(Debug)]
pub struct Saved {
    store: Option<Arc<Store>>,
    names: Vec<String>,
    encoders: Vec<(Encoder, bool, ScalingStamp)>,
    loaded: Vec<AxisParams>,
    memory: Mutex<Vec<Memory>>,
}

impl Saved {
    /// Nothing saved and nothing to save to (the demo, tests, a service without a state
    /// directory): every axis starts from its configuration.
    pub fn none(config: &Config) -> Self {
        Self::with(None, config, Vec::new())
    }

    /// What `store` holds for the axes of `config` (nothing when `store` is none). A
    /// damaged file is an error naming it: the service must not start on it.
    pub fn load(store: Option<Arc<Store>>, config: &Config) -> Result<Self, PersistError> {
        let loaded = match &store {
            Some(s) => s.load_all(config.axes.iter().map(|a| a.name.as_str()))?,
            None => Vec::new(),
        };
        Ok(Self::with(store, config, loaded))
    }

    fn with(store: Option<Arc<Store>>, config: &Config, mut loaded: Vec<AxisParams>) -> Self {
        let names: Vec<String> = config.axes.iter().map(|a| a.name.clone()).collect();
        if loaded.len() != names.len() {
            loaded = names.iter().map(|n| AxisParams::new(n)).collect();
        }
        let memory = config
            .kernel_axes
            .iter()
            .zip(&loaded)
            .map(|(k, p)| {
                let defaults = k
                    .move_home
                    .unwrap_or_else(|| MoveHome::defaults(k.max.vmax, k.max.amax, k.max.jmax));
                // A saved set is whole (the file holds every parameter); a file edited
                // by hand to leave one out gets its default.
                let step = p.step_switch.and_then(|s| s.merged(None, &k.defaults).ok());
                Memory {
                    home: p
                        .home
                        .map_or(defaults, |h| MoveHomeCall::from(h).merged(&defaults)),
                    step,
                    method: p.home_method.unwrap_or_default(),
                    defaults: k.defaults,
                    ptp: p.ptp.unwrap_or_default(),
                    offset: p.position.map(|o| o.offset),
                    commutation: p.commutation_offset,
                }
            })
            .collect();
        let encoders = config
            .axes
            .iter()
            .map(|a| (a.encoder, a.homed_at_start, ScalingStamp::of(a)))
            .collect();
        Self {
            store,
            names,
            encoders,
            loaded,
            memory: Mutex::new(memory),
        }
    }

    /// The store, when the service has a state directory.
    pub fn store(&self) -> Option<&Arc<Store>> {
        self.store.as_ref()
    }

    /// Each axis' file as it was at start.
    pub fn loaded(&self) -> &[AxisParams] {
        &self.loaded
    }

    /// Puts the saved homing parameters into the kernel's configuration of each axis
    /// (the kernel starts each axis with them: `AxisConfig::move_home`).
    pub fn apply_to(&self, config: &mut Config) {
        let memory = self.lock();
        for (k, m) in config.kernel_axes.iter_mut().zip(memory.iter()) {
            k.move_home = Some(m.home);
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Memory>> {
        self.memory.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn name(&self, axis: usize) -> &str {
        self.names.get(axis).map_or("", String::as_str)
    }

    /// Saves through `change` if there is a store; the file's path.
    fn save(
        &self,
        axis: usize,
        change: impl FnOnce(&mut AxisParams),
    ) -> Result<Option<PathBuf>, PersistError> {
        let Some(store) = &self.store else {
            return Ok(None);
        };
        let name = self.name(axis);
        store.update(name, change)?;
        Ok(Some(store.path_of(name)))
    }

    /// The parameters a homing call runs with: those it gives, the saved ones for the
    /// rest.
    pub fn home_run(&self, axis: usize, call: &MoveHomeCall) -> Option<MoveHome> {
        self.lock().get(axis).map(|m| call.merged(&m.home))
    }

    /// A MoveHome call was accepted by the axis: MoveHome is the homing run a call
    /// without a method repeats, and `run` the saved parameters from now on when the call
    /// `gave` some. Blocks to write the file (see the module's doc); `Ok(None)` without a
    /// state directory.
    pub fn home_accepted(
        &self,
        axis: usize,
        run: MoveHome,
        gave: bool,
    ) -> Result<Option<PathBuf>, PersistError> {
        if let Some(m) = self.lock().get_mut(axis) {
            if gave {
                m.home = run;
            }
            m.method = HomeMethod::MoveHome;
        }
        self.save(axis, |p| {
            if gave {
                p.home = Some(HomeParams::from(run));
            }
            // Absent is MoveHome (and keeps a file without step-to-switch homing format 1).
            p.home_method = None;
        })
    }

    /// The homing run a `home` call that names no method repeats: the axis' last.
    pub fn home_method(&self, axis: usize) -> HomeMethod {
        self.lock().get(axis).map(|m| m.method).unwrap_or_default()
    }

    /// The step-to-absolute-switch run a call asks for: what it gives, the saved ones for
    /// the rest, the axis' defaults for what neither has; a parameter without a default
    /// (direction, switch mode, velocity) that neither has is refused by name.
    pub fn step_switch_run(
        &self,
        axis: usize,
        call: &StepSwitchParams,
    ) -> Result<StepAbsoluteSwitch, StepSwitchNotGiven> {
        let memory = self.lock();
        let m = memory.get(axis).ok_or(StepSwitchNotGiven::NoAxis(axis))?;
        call.merged(m.step.as_ref(), &m.defaults)
            .map_err(|NotGiven(parameter)| StepSwitchNotGiven::Parameter {
                axis: self.name(axis).to_string(),
                parameter,
            })
    }

    /// A step-to-absolute-switch call was accepted by the axis: `run` is the saved set,
    /// and step-to-switch the homing run a call without a method repeats, from now on.
    /// Blocks to write the file.
    pub fn step_switch_accepted(
        &self,
        axis: usize,
        run: StepAbsoluteSwitch,
    ) -> Result<Option<PathBuf>, PersistError> {
        if let Some(m) = self.lock().get_mut(axis) {
            m.step = Some(run);
            m.method = HomeMethod::StepToSwitch;
        }
        self.save(axis, |p| {
            p.step_switch = Some(StepSwitchParams::from(run));
            p.home_method = Some(HomeMethod::StepToSwitch);
        })
    }

    /// The dynamics a move runs with: those it gives, the saved ones for the rest.
    pub fn ptp_used(&self, axis: usize, given: PtpParams) -> PtpParams {
        self.lock()
            .get(axis)
            .map_or(given, |m| m.ptp.overlaid(given))
    }

    /// A move with dynamics was accepted: `used` ([`Saved::ptp_used`]) are the saved ones
    /// from now on. Blocks to write the file.
    pub fn ptp_accepted(
        &self,
        axis: usize,
        used: PtpParams,
    ) -> Result<Option<PathBuf>, PersistError> {
        if let Some(m) = self.lock().get_mut(axis) {
            m.ptp = used;
        }
        self.save(axis, |p| p.ptp = Some(used))
    }

    /// The commutation offset saved for `axis` (drive units), if any.
    pub fn commutation_offset(&self, axis: usize) -> Option<i32> {
        self.lock().get(axis).and_then(|m| m.commutation)
    }

    /// Saves a measured commutation offset (drive units) for `axis`. Blocks to write the
    /// file; `Ok(None)` without a state directory (nothing is saved: say so).
    pub fn save_commutation_offset(
        &self,
        axis: usize,
        offset: i32,
    ) -> Result<Option<PathBuf>, PersistError> {
        if let Some(m) = self.lock().get_mut(axis) {
            m.commutation = Some(offset);
        }
        self.save(axis, |p| p.commutation_offset = Some(offset))
    }

    /// What axis `axis` does with its position at start (SPEC §1: an absolute axis'
    /// position is restored from the saved offset; it is homed only when the
    /// configuration says so).
    pub fn start_position(&self, axis: usize) -> StartPosition {
        let Some(&(encoder, homed_at_start, stamp)) = self.encoders.get(axis) else {
            return StartPosition::Incremental;
        };
        if encoder != Encoder::Absolute {
            return StartPosition::Incremental;
        }
        let not = |reason: String| StartPosition::NotRestored {
            reason,
            homed_at_start,
        };
        let Some(store) = &self.store else {
            return not(
                "no state directory ([service] state_dir or systemd's StateDirectory=), so \
                 no position offset is saved"
                    .into(),
            );
        };
        let path = store.path_of(self.name(axis));
        match self.loaded.get(axis).and_then(|p| p.position) {
            None => not(format!(
                "no position offset is saved in {} yet: home the axis (or set its position) \
                 once",
                path.display()
            )),
            Some(saved) if saved.scaling != stamp => not(format!(
                "the position offset in {} was saved under another scaling ({:?}; now \
                 {:?}): home the axis again",
                path.display(),
                saved.scaling,
                stamp
            )),
            Some(saved) => StartPosition::Restore {
                offset: saved.offset,
                homed: homed_at_start,
            },
        }
    }

    /// Whether an axis has an absolute encoder (whose offset is watched and saved).
    pub fn has_absolute(&self) -> bool {
        self.encoders.iter().any(|e| e.0 == Encoder::Absolute)
    }

    /// The absolute axes whose position offset changed while homed, in `snap`: their
    /// new offsets (remembered at once), to be saved with [`Saved::save_offset`].
    pub fn offsets_to_save(&self, snap: &Snapshot) -> Vec<(usize, f64)> {
        let mut memory = self.lock();
        let mut out = Vec::new();
        for (i, (s, m)) in snap.axes.iter().zip(memory.iter_mut()).enumerate() {
            let absolute = self
                .encoders
                .get(i)
                .is_some_and(|e| e.0 == Encoder::Absolute);
            if !absolute || !s.bits.homed || !s.position_offset.is_finite() {
                continue;
            }
            let same = m
                .offset
                .is_some_and(|o| (o - s.position_offset).abs() <= 1e-12 * o.abs().max(1.0));
            if !same {
                m.offset = Some(s.position_offset);
                out.push((i, s.position_offset));
            }
        }
        out
    }

    /// Saves an absolute axis' position offset with the scaling it holds under. Blocks.
    pub fn save_offset(&self, axis: usize, offset: f64) -> Result<Option<PathBuf>, PersistError> {
        let Some(&(_, _, scaling)) = self.encoders.get(axis) else {
            return Ok(None);
        };
        self.save(axis, |p| {
            p.position = Some(PositionOffset { offset, scaling })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::persist::Store;
    use gantry_kernel::axis::command::MoveDirection;

    const EXAMPLE: &str = include_str!("../../../deploy/examples/veth-4-axes.toml");
    const X: &str = "software_limits = [-10.0, 400.0]   # active once homed";

    fn config(x_extra: &str) -> Config {
        let text = EXAMPLE.replacen(X, &format!("{X}\n{x_extra}"), 1);
        Config::parse(&text, "g.toml").unwrap()
    }

    fn store(tag: &str) -> Arc<Store> {
        let d = std::env::temp_dir().join(format!("gantry-saved-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        Arc::new(Store::open(&d).unwrap())
    }

    #[test]
    fn a_home_call_without_parameters_runs_with_the_saved_ones_after_a_restart() {
        let s = store("home");
        let mut c = config("");
        let saved = Saved::load(Some(s.clone()), &c).unwrap();
        let call = MoveHomeCall {
            direction: Some(MoveDirection::Negative),
            normal_position: Some(7.0),
            ..MoveHomeCall::default()
        };
        let run = saved.home_run(0, &call).unwrap();
        assert_eq!(run.normal_position, 7.0);
        assert_eq!(
            saved.home_accepted(0, run, true).unwrap(),
            Some(s.path_of("x"))
        );
        // Restarted: the kernel starts with them, and an empty call runs them.
        let again = Saved::load(Some(s.clone()), &c).unwrap();
        assert_eq!(again.home_run(0, &MoveHomeCall::default()), Some(run));
        again.apply_to(&mut c);
        assert_eq!(c.kernel_axes[0].move_home, Some(run));
        // Other axes keep the kernel's defaults.
        let k = &c.kernel_axes[1];
        assert_eq!(
            c.kernel_axes[1].move_home,
            Some(MoveHome::defaults(k.max.vmax, k.max.amax, k.max.jmax))
        );
        let _ = std::fs::remove_dir_all(s.dir());
    }

    #[test]
    fn step_switch_homing_and_the_last_homing_run_are_kept_across_a_restart() {
        use crate::service::protocol::{StepDirection, StepSwitchMode};
        use gantry_kernel::homing::{HomeDirection, SwitchMode};
        let s = store("step");
        let c = config("");
        let saved = Saved::load(Some(s.clone()), &c).unwrap();
        assert_eq!(saved.home_method(0), HomeMethod::MoveHome);
        // Nothing saved: direction, switch mode and velocity are needed.
        let e = saved
            .step_switch_run(0, &StepSwitchParams::default())
            .unwrap_err();
        assert_eq!(
            e,
            StepSwitchNotGiven::Parameter {
                axis: "x".into(),
                parameter: "direction"
            }
        );
        assert!(
            e.to_string().contains("no direction given")
                && e.to_string().contains("\"x\" has none saved"),
            "{e}"
        );
        let call = StepSwitchParams {
            direction: Some(StepDirection::Negative),
            switch_mode: Some(StepSwitchMode::FallingEdge),
            velocity: Some(4.0),
            set_position: Some(2.0),
            ..StepSwitchParams::default()
        };
        let run = saved.step_switch_run(0, &call).unwrap();
        let k = &c.kernel_axes[0];
        assert_eq!(
            (run.direction, run.switch_mode, run.velocity, run.position),
            (HomeDirection::Negative, SwitchMode::FallingEdge, 4.0, 2.0)
        );
        assert_eq!(
            (run.acceleration, run.deceleration, run.jerk),
            (
                k.defaults.acceleration,
                k.defaults.deceleration,
                k.defaults.jerk
            )
        );
        saved.step_switch_accepted(0, run).unwrap();
        assert_eq!(saved.home_method(0), HomeMethod::StepToSwitch);
        assert_eq!(saved.home_method(1), HomeMethod::MoveHome);
        // Restarted: the run and the method are back; an empty call runs the saved set,
        // a call that gives one parameter changes only that one.
        let again = Saved::load(Some(s.clone()), &c).unwrap();
        assert_eq!(again.home_method(0), HomeMethod::StepToSwitch);
        assert_eq!(
            again.step_switch_run(0, &StepSwitchParams::default()),
            Ok(run)
        );
        let faster = StepSwitchParams {
            velocity: Some(8.0),
            ..StepSwitchParams::default()
        };
        assert_eq!(
            again
                .step_switch_run(0, &faster)
                .map(|r| (r.velocity, r.position)),
            Ok((8.0, 2.0))
        );
        // A MoveHome call without parameters makes MoveHome the axis' run again and keeps
        // the step-to-switch set for the next such call.
        let home = again.home_run(0, &MoveHomeCall::default()).unwrap();
        again.home_accepted(0, home, false).unwrap();
        assert_eq!(again.home_method(0), HomeMethod::MoveHome);
        let third = Saved::load(Some(s.clone()), &c).unwrap();
        assert_eq!(third.home_method(0), HomeMethod::MoveHome);
        assert_eq!(
            third.step_switch_run(0, &StepSwitchParams::default()),
            Ok(run)
        );
        assert_eq!(third.loaded()[0].home, None, "no MoveHome parameters given");
        let _ = std::fs::remove_dir_all(s.dir());
    }

    #[test]
    fn ptp_dynamics_and_the_commutation_offset_are_kept() {
        let s = store("ptp");
        let c = config("");
        let saved = Saved::load(Some(s.clone()), &c).unwrap();
        let used = saved.ptp_used(
            1,
            PtpParams {
                speed: Some(5.0),
                ..PtpParams::default()
            },
        );
        saved.ptp_accepted(1, used).unwrap();
        saved.save_commutation_offset(1, -77).unwrap();
        let again = Saved::load(Some(s.clone()), &c).unwrap();
        let next = again.ptp_used(
            1,
            PtpParams {
                jerk: Some(9.0),
                ..PtpParams::default()
            },
        );
        assert_eq!(
            (next.speed, next.jerk, next.acceleration),
            (Some(5.0), Some(9.0), None)
        );
        assert_eq!(again.commutation_offset(1), Some(-77));
        assert_eq!(again.commutation_offset(0), None);
        // Without a state directory nothing is written, and nothing fails.
        let none = Saved::none(&c);
        assert_eq!(none.save_commutation_offset(0, 1).unwrap(), None);
        assert_eq!(none.commutation_offset(0), Some(1));
        let _ = std::fs::remove_dir_all(s.dir());
    }

    #[test]
    fn an_absolute_axis_restores_its_offset_and_is_homed_only_when_told() {
        let s = store("absolute");
        let told = config("encoder = \"absolute\"\nhomed_at_start = true");
        let not_told = config("encoder = \"absolute\"");
        let saved = Saved::load(Some(s.clone()), &told).unwrap();
        assert!(matches!(
            saved.start_position(0),
            StartPosition::NotRestored { homed_at_start: true, ref reason }
                if reason.contains("no position offset is saved") && reason.contains("x.params")
        ));
        assert_eq!(saved.start_position(1), StartPosition::Incremental);
        // Homed in this run with an offset: it is to be saved, once.
        let mut snap = Snapshot {
            axes: vec![Default::default(); 4],
            ..Snapshot::default()
        };
        snap.axes[0].position_offset = 12.5;
        assert!(
            saved.offsets_to_save(&snap).is_empty(),
            "not homed: nothing to save"
        );
        snap.axes[0].bits.homed = true;
        snap.axes[1].bits.homed = true;
        snap.axes[1].position_offset = 3.0;
        assert_eq!(
            saved.offsets_to_save(&snap),
            vec![(0, 12.5)],
            "incremental y not saved"
        );
        assert!(saved.offsets_to_save(&snap).is_empty());
        saved.save_offset(0, 12.5).unwrap();
        let restarted = Saved::load(Some(s.clone()), &told).unwrap();
        assert_eq!(
            restarted.start_position(0),
            StartPosition::Restore {
                offset: 12.5,
                homed: true
            }
        );
        let restarted = Saved::load(Some(s.clone()), &not_told).unwrap();
        assert_eq!(
            restarted.start_position(0),
            StartPosition::Restore {
                offset: 12.5,
                homed: false
            }
        );
        // Another scaling: the offset means nothing any more.
        let regeared = Config::parse(
            &EXAMPLE
                .replacen(
                    X,
                    &format!("{X}\nencoder = \"absolute\"\nhomed_at_start = true"),
                    1,
                )
                .replacen("motor_revs = 1 ", "motor_revs = 3 ", 1),
            "g.toml",
        )
        .unwrap();
        assert_eq!(regeared.axes[0].scaling.motor_revs, 3);
        let restarted = Saved::load(Some(s.clone()), &regeared).unwrap();
        assert!(matches!(
            restarted.start_position(0),
            StartPosition::NotRestored { ref reason, .. } if reason.contains("another scaling")
        ));
        // No state directory: said so.
        assert!(matches!(
            Saved::none(&told).start_position(0),
            StartPosition::NotRestored { ref reason, .. } if reason.contains("no state directory")
        ));
        let _ = std::fs::remove_dir_all(s.dir());
    }
}
