//! Starting and ending master relations: MC_GearIn, MC_GearInPos, MC_CamIn, MC_GearOut,
//! MC_CamOut. Each starts from the follower's last set values, so it begins without a
//! jump; the catch-up ([`crate::sync::catch`]) takes it onto the law.

use crate::axis::command::{finite, positive, CommandError, Operand, RangeProblem};
use crate::axis::handle::{CommandStatus, HandleId, HandleTable};
use crate::axis::motion::Epoch;
use crate::axis::state::Event;
use crate::axis::Axis;
use crate::cam::CamTable;
use crate::profile::{plan_position, plan_velocity, KinematicState, Limits, Profile, RampType};
use crate::sync::catch::Catch;
use crate::sync::command::{CamIn, CamStart, CatchUp, GearIn, GearInPos, MasterJog, MasterValue};
use crate::sync::law::{CamLaw, JogLaw, Law};
use crate::sync::{Follow, MasterSample, Split};

/// What a synchronised-motion command needs from outside its axis: the master's values
/// this cycle (checked by the kernel: it exists, is not the follower, forms no loop) and
/// the cam tables.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SyncContext<'a> {
    /// The named master's values (`None` for other commands).
    pub master: Option<MasterSample>,
    /// The kernel's cam tables.
    pub cams: &'a [Option<CamTable>],
}

impl Axis {
    /// The master's sample for a command, or why it cannot be followed.
    fn master_for(
        name: &'static str,
        master: usize,
        sync: &SyncContext<'_>,
    ) -> Result<MasterSample, CommandError> {
        let m = sync.master.ok_or(CommandError::BadMaster {
            command: name,
            master,
            why: "there is no such axis",
        })?;
        if !m.available {
            return Err(CommandError::MasterNotAvailable {
                command: name,
                master,
            });
        }
        Ok(m)
    }

    /// The catch-up's limits and ramp: the command's or the axis' defaults, within its
    /// maxima.
    fn catch_limits(
        &self,
        name: &'static str,
        c: &CatchUp,
        speed: f64,
    ) -> Result<(Limits, RampType), CommandError> {
        let d = self.cfg.defaults;
        let max = self.cfg.max;
        let acc = positive(
            name,
            Operand::Acceleration,
            c.acceleration.unwrap_or(d.acceleration),
            max.amax,
        )?;
        let dec = positive(
            name,
            Operand::Deceleration,
            c.deceleration.unwrap_or(d.deceleration),
            max.dmax,
        )?;
        let jerk = positive(name, Operand::Jerk, c.jerk.unwrap_or(d.jerk), max.jmax)?;
        Ok((
            Limits {
                vmax: max.vmax.max(speed.abs()),
                amax: acc,
                dmax: dec,
                jmax: jerk,
            },
            c.ramp.unwrap_or(d.ramp),
        ))
    }

    fn gear_ratio(name: &'static str, g: &GearIn) -> Result<(i64, i64), CommandError> {
        let bad = |value: f64, problem| CommandError::OperandOutOfRange {
            command: name,
            operand: Operand::Ratio,
            value,
            problem,
            limit: f64::NAN,
        };
        if g.denominator == 0 {
            return Err(bad(0.0, RangeProblem::NotPositive));
        }
        if g.numerator == 0 {
            return Err(CommandError::CannotSynchronise {
                command: name,
                why: "a ratio numerator of 0 would stand the follower still; use Halt",
            });
        }
        Ok((g.numerator as i64, g.denominator as i64))
    }

    /// The follower's own motion minus the law's at the start: where `e` begins.
    fn catch_start(&self, d1: f64, d2: f64, m: &MasterSample) -> KinematicState {
        let s = self.main;
        KinematicState {
            p: 0.0,
            v: s.v - d1 * m.v,
            a: if m.actual {
                s.a
            } else {
                s.a - (d2 * m.v * m.v + d1 * m.a)
            },
            j: 0.0,
        }
    }

    fn plan_catch(
        name: &'static str,
        start: KinematicState,
        offset: Option<f64>,
        limits: &Limits,
        ramp: RampType,
    ) -> Result<Profile, CommandError> {
        let plan = |ramp| match offset {
            Some(d) => plan_position(ramp, start, d, 0.0, limits),
            None => plan_velocity(ramp, start, 0.0, limits),
        };
        plan(ramp)
            .or_else(|_| plan(RampType::Trapezoid))
            .map_err(|error| CommandError::Plan {
                command: name,
                error,
            })
    }

    /// A relation whose law counts from where master and follower are now and whose
    /// catch-up is `profile` in time, from this cycle.
    fn relation_from_here(
        &self,
        name: &'static str,
        h: HandleId,
        (master, source): (usize, MasterValue),
        law: Law,
        m: &MasterSample,
        (profile, limits, ramp): (Profile, Limits, RampType),
    ) -> Follow {
        Follow {
            master,
            source,
            law,
            master_ref: m.at,
            follower_ref: self.set_split(),
            catch: Catch::Time {
                profile,
                epoch: Epoch::at(self.last_tick),
            },
            handle: h,
            command: name,
            catch_limits: (limits, ramp),
        }
    }

    /// Installs a relation: the old one and any own motion end (Aborted).
    fn start_follow(&mut self, f: Follow, handles: &mut HandleTable) {
        if let Some(old) = self.follow.replace(f) {
            handles.set(old.handle, CommandStatus::Aborted);
        }
        if let Some(m) = self.motion.take() {
            handles.set(m.handle, CommandStatus::Aborted);
        }
        self.queue
            .drain(|q| handles.set(q.handle(), CommandStatus::Aborted));
        self.enter(Event::SynchronizedMotionStarted);
    }

    pub(super) fn gear_in(
        &mut self,
        g: &GearIn,
        sync: &SyncContext<'_>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = "GearIn";
        let (num, den) = Self::gear_ratio(name, g)?;
        let m = Self::master_for(name, g.master, sync)?;
        let ratio = num as f64 / den as f64;
        let start = self.catch_start(ratio, 0.0, &m);
        let (limits, ramp) = self.catch_limits(name, &g.catch_up, start.v)?;
        let profile = Self::plan_catch(name, start, None, &limits, ramp)?;
        let law = Law::Gear {
            numerator: num,
            denominator: den,
        };
        let f = self.relation_from_here(
            name,
            h,
            (g.master, g.source),
            law,
            &m,
            (profile, limits, ramp),
        );
        self.start_follow(f, handles);
        Ok(CommandStatus::Active)
    }

    pub(super) fn gear_in_pos(
        &mut self,
        g: &GearInPos,
        sync: &SyncContext<'_>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = "GearInPos";
        let (num, den) = Self::gear_ratio(name, &g.gear)?;
        let m = Self::master_for(name, g.gear.master, sync)?;
        let ratio = num as f64 / den as f64;
        let ms = finite(name, Operand::SyncPosition, g.master_sync_position)?;
        let ss = finite(name, Operand::SyncPosition, g.slave_sync_position)?;
        let outside = |value: f64, period: f64| CommandError::OperandOutOfRange {
            command: name,
            operand: Operand::SyncPosition,
            value,
            problem: RangeProblem::OutsidePeriod,
            limit: period,
        };
        if let Some(pm) = m.period {
            if !(0.0..pm).contains(&ms) {
                return Err(outside(ms, pm));
            }
        }
        if let Some(pf) = self.period() {
            if !(0.0..pf).contains(&ss) {
                return Err(outside(ss, pf));
            }
        }
        let distance = match g.master_start_distance {
            Some(d) => Some(positive(name, Operand::StartDistance, d, f64::MAX)?),
            None => None,
        };
        let eps_v = 1e-9 * self.cfg.max.vmax;
        let master_moves = m.v.abs() > 1e-12;
        let dir = if master_moves { m.v.signum() } else { 1.0 };
        let standing = self.main.v.abs() <= eps_v && self.main.a.abs() <= 1e-9 * self.cfg.max.amax;
        if distance.is_some() && !standing {
            return Err(CommandError::CannotSynchronise {
                command: name,
                why: "with a master start distance the follower must stand until the master \
                      gets there; halt it first",
            });
        }
        if !master_moves && !standing {
            return Err(CommandError::CannotSynchronise {
                command: name,
                why: "the follower moves while the master stands: its position cannot be \
                      matched to the master's",
            });
        }
        // The sync position ahead of the master (in its direction), at least the start
        // distance away.
        let needed = distance.unwrap_or(0.0);
        let mut sync_at = Split {
            turns: if m.period.is_some() { m.at.turns } else { 0 },
            p: ms,
        };
        let ahead = dir * (ms - m.at.p);
        match m.period {
            Some(pm) => {
                let short = needed - ahead;
                if short > 0.0 || (ahead <= 0.0 && distance.is_none()) {
                    let n = ((short.max(0.0)) / pm).floor() as i64 + 1;
                    sync_at.turns += if dir > 0.0 { n } else { -n };
                }
            }
            None => {
                if ahead < needed || (ahead <= 0.0 && distance.is_none()) {
                    return Err(CommandError::CannotSynchronise {
                        command: name,
                        why: "the master sync position is behind the master (or closer than \
                              the master start distance)",
                    });
                }
            }
        }
        let to_sync = m.delta_f64(&sync_at); // master travel from the sync position: < 0 ahead
        let start = match distance {
            Some(d) => -dir * d,
            None => to_sync,
        };
        // Follower position at the start of the catch-up relative to the gear line through
        // (sync_at, ss): e0, taken the short way round on a modulo follower.
        let here = self.set_split();
        let mut x = here.p - ss - ratio * start;
        let mut turns = here.turns;
        if let Some(pf) = self.period() {
            let n = (x / pf).round();
            x -= n * pf;
            turns = turns.saturating_add(n as i64);
        }
        let (limits, ramp) = self.catch_limits(name, &g.gear.catch_up, 0.0)?;
        let len = -start;
        let (de_dm, d2e_dm2) = if distance.is_some() || !master_moves {
            (-ratio, 0.0)
        } else {
            let de = (self.main.v - ratio * m.v) / m.v;
            let d2 = if m.actual {
                0.0
            } else {
                (self.main.a - ratio * m.a - de * m.a) / (m.v * m.v)
            };
            (de, d2)
        };
        let f = Follow {
            master: g.gear.master,
            source: g.gear.source,
            law: Law::Gear {
                numerator: num,
                denominator: den,
            },
            master_ref: sync_at,
            follower_ref: Split { turns, p: ss },
            catch: Catch::quintic(x, de_dm * len, d2e_dm2 * len * len, start),
            handle: h,
            command: name,
            catch_limits: (limits, ramp),
        };
        self.start_follow(f, handles);
        Ok(CommandStatus::Active)
    }

    pub(super) fn cam_in(
        &mut self,
        c: &CamIn,
        sync: &SyncContext<'_>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = "CamIn";
        let table = sync.cams.get(c.table).and_then(Option::as_ref).ok_or(
            CommandError::NoSuchCamTable {
                command: name,
                table: c.table,
            },
        )?;
        let m = Self::master_for(name, c.master, sync)?;
        for v in [c.master_scaling, c.slave_scaling] {
            if !(v.is_finite() && v != 0.0) {
                return Err(CommandError::OperandOutOfRange {
                    command: name,
                    operand: Operand::Scaling,
                    value: v,
                    problem: if v.is_finite() {
                        RangeProblem::NotPositive
                    } else {
                        RangeProblem::NotFinite
                    },
                    limit: f64::NAN,
                });
            }
        }
        let mo = finite(name, Operand::Offset, c.master_offset)?;
        let so = finite(name, Operand::Offset, c.slave_offset)?;
        let (x0, x1) = table.master_range();
        let x_ref = match c.start {
            CamStart::Absolute => mo + c.master_scaling * m.at.p,
            CamStart::Relative => x0 + mo,
        };
        if !c.periodic && !(x0..=x1).contains(&x_ref) {
            return Err(CommandError::CannotSynchronise {
                command: name,
                why: "the master is outside the non-periodic table's master range",
            });
        }
        let (cycle, phase) = CamLaw::locate(table, x_ref, c.periodic);
        let y_ref = c.slave_scaling * CamLaw::unrolled(table, x_ref, c.periodic);
        let at = table.eval(phase);
        let d1 = c.slave_scaling * at.d1 * c.master_scaling;
        let d2 = c.slave_scaling * at.d2 * c.master_scaling * c.master_scaling;
        let start = self.catch_start(d1, d2, &m);
        let offset = match c.start {
            CamStart::Absolute => {
                let mut d = so + y_ref - self.main.p;
                if let Some(pf) = self.period() {
                    d -= (d / pf).round() * pf;
                }
                Some(d)
            }
            CamStart::Relative => (so != 0.0).then_some(so),
        };
        let (limits, ramp) = self.catch_limits(name, &c.catch_up, start.v)?;
        let profile = Self::plan_catch(name, start, offset, &limits, ramp)?;
        let law = Law::Cam(CamLaw {
            table: c.table,
            periodic: c.periodic,
            master_scaling: c.master_scaling,
            slave_scaling: c.slave_scaling,
            x_ref,
            y_ref,
            cycle,
            segment: 0,
        });
        let f = self.relation_from_here(
            name,
            h,
            (c.master, c.source),
            law,
            &m,
            (profile, limits, ramp),
        );
        self.start_follow(f, handles);
        Ok(CommandStatus::Active)
    }

    /// A master-driven jog (Logix MAJ with MDAC): the follower moves `speed` units per
    /// master unit in the jog's direction while its lock holds.
    pub(super) fn master_jog(
        &mut self,
        j: &MasterJog,
        sync: &SyncContext<'_>,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let name = "Jog.MasterDriven";
        let m = Self::master_for(name, j.master, sync)?;
        let speed = positive(name, Operand::Speed, j.speed, f64::MAX)?;
        if !self.direction_allowed(j.direction.sign()) {
            return Err(self.direction_error(name, j.direction.sign()));
        }
        let only = j.lock.only();
        // The follower goes the jog's direction while the lock holds: against a master
        // that may only lock going backwards, the ratio's sign turns.
        let ratio = j.direction.sign() * speed * if only < 0.0 { -1.0 } else { 1.0 };
        let wait_at = if j.lock.waits_for_position() {
            let lp = finite(name, Operand::Position, j.lock_position)?;
            // The lock position ahead of the master in the lock's direction.
            let mut at = Split {
                turns: if m.period.is_some() { m.at.turns } else { 0 },
                p: lp,
            };
            if let Some(pm) = m.period {
                if !(0.0..pm).contains(&lp) {
                    return Err(CommandError::OperandOutOfRange {
                        command: name,
                        operand: Operand::Position,
                        value: lp,
                        problem: RangeProblem::OutsidePeriod,
                        limit: pm,
                    });
                }
                if only * (lp - m.at.p) < 0.0 {
                    at.turns += if only > 0.0 { 1 } else { -1 };
                }
            }
            Some(at)
        } else {
            None
        };
        let locked = wait_at.is_none() && (only == 0.0 || m.v * only > 0.0);
        let d1 = if locked { ratio } else { 0.0 };
        let start = self.catch_start(d1, 0.0, &m);
        let (limits, ramp) = self.catch_limits(name, &j.catch_up, start.v)?;
        let profile = Self::plan_catch(name, start, None, &limits, ramp)?;
        let law = Law::Jog(JogLaw {
            ratio,
            only,
            wait_at,
            locked,
            anchor: m.at,
            travel: 0.0,
        });
        let f = self.relation_from_here(
            name,
            h,
            (j.master, j.source),
            law,
            &m,
            (profile, limits, ramp),
        );
        self.start_follow(f, handles);
        self.last_direction = j.direction.sign();
        Ok(CommandStatus::Active)
    }

    /// GearOut / CamOut: the relation is Done and the axis goes on at its velocity.
    pub(super) fn sync_out(
        &mut self,
        name: &'static str,
        cam: bool,
        h: HandleId,
        handles: &mut HandleTable,
    ) -> Result<CommandStatus, CommandError> {
        let what = if cam { "camming" } else { "gearing" };
        let f = match self.follow {
            Some(f) if (cam && f.is_cam()) || (!cam && f.is_gear()) => f,
            _ => {
                return Err(CommandError::NotSynchronised {
                    command: name,
                    what,
                })
            }
        };
        handles.set(f.handle, CommandStatus::Done);
        self.follow = None;
        let carry = handles.issue(CommandStatus::Active);
        self.continue_at_velocity(carry, name, Epoch::at(self.last_tick));
        let _ = h;
        Ok(CommandStatus::Done)
    }
}
