//! `gantry run --config FILE`: the master as a service. The cycle thread (real time
//! unless `--no-rt`) brings the bus up and runs the engine; the main thread serves the
//! control socket and handles signals: the first SIGINT/SIGTERM quick-stops moving axes,
//! disables the drives and takes the bus to PreOp; a second one exits at once.

pub mod group;
pub mod protocol;
pub mod server;
pub mod sync;

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

use thiserror::Error;

use crate::bus::{AnyBus, BusError};
use crate::config::{Config, ConfigError};
use crate::error_chain::Chain;
use crate::ethercat::link::LinkFactory;
use crate::persist::{self, Saved, StartPosition, Store};
use crate::runtime::controller::Controller;
use crate::runtime::cycle::{Cycle, SetupError};
use crate::runtime::engine::{AppEnds, Channels, Engine, LateReply};
use crate::runtime::rt::{self, RtError};
use crate::runtime::sdo::{SdoData, SdoError, SdoRequest};
use crate::runtime::stats::{CycleCounters, CycleFigures};
use gantry_kernel::axis::command::Command;
use gantry_kernel::axis::handle::CommandStatus;

/// How `gantry run` was asked to run.
#[derive(Clone, Debug)]
pub struct RunArgs {
    /// Configuration file.
    pub config: String,
    /// Run without real-time scheduling (and say so).
    pub no_rt: bool,
    /// Control socket path.
    pub socket: PathBuf,
}

/// Why the service did not run.
#[derive(Debug, Error)]
pub enum ServiceError {
    /// The configuration is wrong.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Real time is not possible.
    #[error(transparent)]
    RealTime(#[from] RtError),
    /// The bus did not come up.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The cycle does not fit the configuration or its bus.
    #[error(transparent)]
    Cycle(#[from] SetupError),
    /// A thread or the control socket's runtime could not be started.
    #[error("cannot start {what}")]
    Start {
        /// What.
        what: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The cycle thread ended without saying why (it panicked).
    #[error("the cycle thread {0}")]
    CycleThread(&'static str),
    /// A saved parameter file is damaged, or the state directory is unusable: the
    /// service does not start on it.
    #[error("saved axis parameters")]
    Persist(#[from] crate::persist::PersistError),
    /// The control socket could not be opened.
    #[error("control socket {path}")]
    Socket {
        /// Its path.
        path: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// Name of the cycle thread (what `ps -L`, `top -H` and /proc show).
pub const CYCLE_THREAD: &str = "gantry-cycle";

/// Stack of the cycle thread: the main thread's default, room for the frames of
/// ethercrab's futures it polls each cycle in a debug build (the bring-up's, larger, run
/// in a thread of their own). Locked with the rest of the memory (`rt.lock_memory`).
pub const CYCLE_STACK_BYTES: usize = 8 << 20;

/// The cycle thread's start, in the thread that will run the cycle: real time (SCHED_FIFO,
/// pinned, memory locked) unless `real_time` is false, then the bus up to SafeOp — this
/// thread exchanges the frames itself on `[bus] interface` or on the link `links` opens
/// (the binary's in-process simulator, whose thread, started from here, inherits this
/// thread's scheduling and CPU) — the cycle (kernel and drive
/// channels) built for it from the configuration ([`Cycle::from_config`]; the cycle takes
/// the slaves on to OP), and the engine with the late-reply policy of the mode (lost at the
/// deadline in real time; waited for without it). The engine is ready for [`Engine::run`]; nothing else runs at
/// SCHED_FIFO (ethercrab's timers are off, see `ethercat::bus::NO_TIMERS`).
pub fn start_cycle(
    config: &Config,
    real_time: bool,
    links: &dyn LinkFactory,
    log: &mut (dyn Write + Send),
) -> Result<(Engine<AnyBus>, AppEnds), ServiceError> {
    if real_time {
        rt::enter(&config.rt)?;
    }
    // The channels first: made after the bus is in Op, their allocation would be a gap in
    // the process data that drives count as missed setpoints (see `Channels`).
    let channels = Channels::new(config.axes.len(), 1 << 16);
    let bus = AnyBus::bring_up(config, links, log)?;
    // The kernel and the drives' channels, for the bus as it came up.
    let cycle = match Cycle::from_config(config, &bus) {
        Ok(cycle) => cycle,
        Err(e) => {
            bus.shut_down(log);
            return Err(e.into());
        }
    };
    let (mut engine, ends) = Engine::with_channels(bus, cycle, config.rt.overrun_limit, channels);
    // Without real time a late reply is the host's fault, not the bus'.
    engine.set_late_reply(if real_time {
        LateReply::Lost
    } else {
        LateReply::WAIT
    });
    Ok((engine, ends))
}

/// Starts the cycle thread ([`CYCLE_THREAD`]): [`start_cycle`], the application's ends
/// (or why it could not start) sent to `ends`, then [`Engine::run`] every `period_ns`
/// until `stop`, then the bus down to PreOp and `links` told its link is closed
/// ([`LinkFactory::closed`]). Returns the cycle's counters at the end (the
/// figures come from the controller, [`Controller::figures`]).
pub fn spawn_cycle_thread(
    config: Config,
    real_time: bool,
    period_ns: u64,
    stop: Arc<AtomicBool>,
    links: Arc<dyn LinkFactory>,
    ends: mpsc::Sender<Result<AppEnds, ServiceError>>,
) -> Result<std::thread::JoinHandle<Option<CycleCounters>>, ServiceError> {
    std::thread::Builder::new()
        .name(CYCLE_THREAD.into())
        .stack_size(CYCLE_STACK_BYTES)
        .spawn(move || -> Option<CycleCounters> {
            let mut log = std::io::stdout();
            let (engine, app) = match start_cycle(&config, real_time, &*links, &mut log) {
                Ok(started) => started,
                Err(e) => {
                    let _ = ends.send(Err(e));
                    return None;
                }
            };
            let _ = ends.send(Ok(app));
            let engine = engine.run(period_ns, &stop);
            let counters = engine.counters();
            engine.into_bus().shut_down(&mut log);
            // What the link's other end has to say, the shutdown included.
            links.closed(&config, &mut log);
            Some(counters)
        })
        .map_err(|source| ServiceError::Start {
            what: "the cycle thread",
            source,
        })
}

/// The state directory's saved parameters of every axis (nothing saved without a state
/// directory, said on `out`). A damaged file or an unusable directory is an error.
pub fn open_saved(config: &Config, out: &mut (dyn Write + Send)) -> Result<Saved, ServiceError> {
    let env = std::env::var_os(persist::STATE_DIRECTORY_ENV);
    let Some((dir, source)) =
        persist::state_dir(config.service.state_dir.as_deref(), env.as_deref())
    else {
        let _ = writeln!(
            out,
            "gantry: no state directory ([service] state_dir, or systemd's \
             StateDirectory=): homing and PTP parameters and position offsets are not saved"
        );
        return Ok(Saved::none(config));
    };
    let store = Arc::new(Store::open(&dir)?);
    let saved = Saved::load(Some(store), config)?;
    let _ = writeln!(
        out,
        "gantry: saved axis parameters in {} (from {})",
        dir.display(),
        source.describe()
    );
    Ok(saved)
}

/// Restores each absolute axis' position from its saved offset and marks it homed when
/// `homed_at_start` says so (SPEC §1), saying what it did on `out`; an absolute axis it
/// cannot restore is left unhomed with the reason.
pub fn restore_positions(
    config: &Config,
    saved: &Saved,
    controller: &Controller,
    out: &mut (dyn Write + Send),
) {
    for (i, a) in config.axes.iter().enumerate() {
        let restored = match saved.start_position(i) {
            StartPosition::Incremental => continue,
            StartPosition::NotRestored {
                reason,
                homed_at_start,
            } => {
                let _ = writeln!(
                    out,
                    "gantry: axis {}: position not restored{}: {reason}",
                    a.name,
                    if homed_at_start {
                        ", not homed at start"
                    } else {
                        ""
                    }
                );
                continue;
            }
            StartPosition::Restore { offset, homed } => {
                let shift = Command::SetPosition {
                    position: offset,
                    relative: true,
                };
                let done = |c: Command| {
                    controller
                        .command(i, c)
                        .map_err(|e| e.to_string())
                        .and_then(|h| h.wait(Duration::from_secs(5)).map_err(|e| e.to_string()))
                        .and_then(|s| match s {
                            CommandStatus::Done => Ok(()),
                            other => Err(format!("{other:?}")),
                        })
                };
                done(shift)
                    .and_then(|()| {
                        if homed {
                            done(Command::SetHomed(true))
                        } else {
                            Ok(())
                        }
                    })
                    .map(|()| (offset, homed))
            }
        };
        let _ = match restored {
            Ok((offset, homed)) => writeln!(
                out,
                "gantry: axis {}: position restored from the saved offset {offset} {}{}",
                a.name,
                a.units,
                if homed {
                    "; homed (homed_at_start)"
                } else {
                    "; not homed (homed_at_start is off)"
                }
            ),
            Err(e) => writeln!(
                out,
                "gantry: axis {}: position not restored, not homed: the axis refused: {e}",
                a.name
            ),
        };
    }
}

/// Writes each axis' saved commutation offset (`gantry commission AXIS commutation`) back
/// to its drive (its `[axis.commutation]` offset object, 0x2100 by default, in the drive's
/// units) before anything can enable it: a drive that lost its setting would hold the
/// motor with the wrong one. A write that fails is said on `out` with the drive's reason;
/// the axis keeps what its drive has.
pub fn restore_commutation(
    config: &Config,
    saved: &Saved,
    controller: &Controller,
    out: &mut (dyn Write + Send),
) {
    for (i, a) in config.axes.iter().enumerate() {
        let Some(offset) = saved.commutation_offset(i) else {
            continue;
        };
        let objects = a.commutation.objects().unwrap_or_default();
        let object = objects.offset;
        let written = drive_offset(controller, a, &objects, offset).and_then(|wire| {
            let bytes = wire.to_le_bytes();
            let data = SdoData::new(bytes.get(..object.kind.size()).unwrap_or(&bytes));
            sdo_blocking(
                controller,
                SdoRequest::download(a.drive, object.index, object.sub, data),
            )
        });
        let _ = match written {
            Ok(_) => writeln!(
                out,
                "gantry: axis {}: commutation offset {offset} counts written to its drive \
                 (0x{:04X}:{:02X}) from the saved parameters",
                a.name, object.index, object.sub
            ),
            Err(e) => writeln!(
                out,
                "gantry: axis {}: the saved commutation offset {offset} counts could NOT be \
                 written to its drive (0x{:04X}:{:02X}): {e}; check the drive's commutation \
                 before enabling it",
                a.name, object.index, object.sub
            ),
        };
    }
}

/// The saved `offset` (counts) in the units of axis `a`'s drive (its `objects`): counts pass as they are;
/// units of an electrical revolution need the motor's pole pairs (given, or read).
fn drive_offset(
    controller: &Controller,
    a: &crate::config::AxisSection,
    objects: &gantry_drives::commutation::CommutationObjects,
    offset: i32,
) -> Result<i64, String> {
    use gantry_drives::commutation::{OffsetUnits, PolePairs};
    if objects.offset_units == OffsetUnits::Counts {
        return Ok(i64::from(offset));
    }
    let pole_pairs = match objects.pole_pairs {
        PolePairs::Fixed(n) => n,
        PolePairs::Object(o) => {
            let d = sdo_blocking(controller, SdoRequest::upload(a.drive, o.index, o.sub))?;
            let n = d.as_slice().first().copied().unwrap_or(0);
            if n == 0 {
                return Err(format!(
                    "the drive reports 0 pole pairs (0x{:04X}:{:02X})",
                    o.index, o.sub
                ));
            }
            u32::from(n)
        }
    };
    let e = f64::from(a.scaling.counts_per_motor_rev) / f64::from(pole_pairs);
    Ok(objects.offset_to_drive(i64::from(offset), e))
}

/// One SDO transfer beside the cycle, waited for (a transfer already on the bus is waited
/// out, for up to 10 s).
fn sdo_blocking(controller: &Controller, request: SdoRequest) -> Result<SdoData, String> {
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        let r = controller
            .sdo(request.clone())
            .map_err(|e| e.to_string())
            .and_then(|h| h.wait(Duration::from_secs(5)).map_err(|e| e.to_string()));
        match r {
            Ok(Err(SdoError::Busy)) if Instant::now() < end => {
                std::thread::sleep(Duration::from_millis(5))
            }
            Ok(r) => return r.map_err(|e| Chain(&e).to_string()),
            Err(e) => return Err(e),
        }
    }
}

/// Saves the position offsets of absolute axes that changed while homed (a blocking
/// write, done on a thread of its own so the control socket goes on).
fn save_offsets(saved: &Arc<Saved>, controller: &Controller) {
    if !saved.has_absolute() || saved.store().is_none() {
        return;
    }
    let snap = controller.snapshot();
    for (axis, offset) in saved.offsets_to_save(&snap) {
        let saved = saved.clone();
        let name = controller.axes().get(axis).cloned().unwrap_or_default();
        tokio::task::spawn_blocking(move || {
            if let Err(e) = saved.save_offset(axis, offset) {
                let _ = writeln!(
                    std::io::stdout(),
                    "gantry: axis {name}: position offset not saved: {}",
                    crate::error_chain::Chain(&e)
                );
            }
        });
    }
}

/// Runs the service until shut down, its bus on `[bus] interface` or on the link `links`
/// opens (the `gantry` binary hands it its in-process simulator's).
pub fn run(
    args: &RunArgs,
    links: Arc<dyn LinkFactory>,
    out: &mut (dyn Write + Send),
) -> Result<CycleFigures, ServiceError> {
    let mut config = Config::load(&args.config)?;
    // The saved parameters first: a damaged file stops the start before the bus moves.
    let saved = Arc::new(open_saved(&config, out)?);
    saved.apply_to(&mut config);
    let real_time = !args.no_rt;
    if real_time {
        rt::check(&config.rt, config.bus.interface.is_some())?;
    } else {
        let _ = writeln!(
            out,
            "gantry: --no-rt: the cycle is NOT real time (no SCHED_FIFO, no locked memory)"
        );
    }
    let period_ns = u64::from(config.bus.cycle_us) * 1000;
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel::<Result<AppEnds, ServiceError>>();
    let cycle_thread = spawn_cycle_thread(
        config.clone(),
        real_time,
        period_ns,
        stop.clone(),
        links,
        tx,
    )?;
    let ends = match rx.recv() {
        Ok(Ok(ends)) => ends,
        Ok(Err(e)) => {
            let _ = cycle_thread.join();
            return Err(e);
        }
        Err(_) => return Err(ServiceError::CycleThread("ended at start")),
    };
    let names = config.axes.iter().map(|a| a.name.clone()).collect();
    // Homing and move parameters are filled in and saved by the controller, whoever
    // sends the command.
    let controller = Controller::with_sdo_max_bytes(ends, names, config.bus.sdo_max_bytes())
        .saving_to(saved.clone())
        .map_err(|source| ServiceError::Start {
            what: "the thread that saves axis parameters",
            source,
        })?;
    restore_positions(&config, &saved, &controller, out);
    restore_commutation(&config, &saved, &controller, out);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|source| ServiceError::Start {
            what: "the control socket's runtime (tokio)",
            source,
        })?;
    let socket = args.socket.clone();
    let listener = runtime
        .block_on(async { server::bind(&socket) })
        .map_err(|source| ServiceError::Socket {
            path: socket.display().to_string(),
            source,
        })?;
    let _ = writeln!(
        out,
        "gantry: {} axes, cycle {} µs{}, control socket {}",
        config.axes.len(),
        config.bus.cycle_us,
        if real_time {
            ", real time"
        } else {
            ", not real time"
        },
        socket.display()
    );
    if real_time && !rt::holds_cpu_dma_latency() {
        let _ = writeln!(
            out,
            "gantry: cannot write /dev/cpu_dma_latency: the CPUs may sleep deeply between \
             cycles and wake late (give this user's group write access to it, as \
             deploy/gantry.service does)"
        );
    }
    let state =
        server::ServerState::with_saved(controller.clone(), config, real_time, saved.clone());
    runtime.block_on(async {
        let server = tokio::spawn(server::serve(listener, state.clone()));
        let mut sigint = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::interrupt()).ok();
        let mut sigterm = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).ok();
        let mut signals = 0;
        let mut tick = tokio::time::interval(Duration::from_millis(5));
        loop {
            tokio::select! {
                _ = async { match sigint.as_mut() { Some(s) => { s.recv().await; } None => std::future::pending().await } } => signals += 1,
                _ = async { match sigterm.as_mut() { Some(s) => { s.recv().await; } None => std::future::pending().await } } => signals += 1,
                _ = tick.tick() => {
                    state.collect_trace();
                    save_offsets(&saved, &controller);
                    if controller.snapshot().ended || cycle_thread.is_finished() {
                        break;
                    }
                    continue;
                }
            }
            if signals == 1 {
                let _ = writeln!(std::io::stdout(), "gantry: stopping (quick stop, disable, bus to PreOp); again to force exit");
                stop.store(true, Ordering::Relaxed);
            } else {
                let _ = writeln!(std::io::stdout(), "gantry: forced exit");
                let _ = std::fs::remove_file(&socket);
                std::process::exit(130);
            }
        }
        // A `gantry trace` still recording gets what was recorded, the stop included.
        state.end_recordings(Duration::from_secs(2)).await;
        server.abort();
    });
    // A save of a command the axis took just before the end is written before gantry ends.
    if let Some(saver) = controller.saver() {
        if !saver.settle(Duration::from_secs(5)) {
            let _ = writeln!(
                out,
                "gantry: parameters of the last commands may not be saved (their saves did \
                 not finish within 5 s)"
            );
        }
    }
    let _ = std::fs::remove_file(&args.socket);
    cycle_thread
        .join()
        .ok()
        .flatten()
        .ok_or(ServiceError::CycleThread("failed (it panicked)"))?;
    let figures = controller.figures();
    let _ = writeln!(
        out,
        "gantry: stopped after {} cycles; wake-up {}; compute {}; round trip {}; overruns {}",
        figures.cycles, figures.wake, figures.compute, figures.round_trip, figures.overruns
    );
    Ok(figures)
}
