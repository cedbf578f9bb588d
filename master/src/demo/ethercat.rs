//! `gantry demo --bus ethercat`: the same kind of demo on *simulated drives on an
//! in-process EtherCAT network*: two CiA-402 servos (CoE, CSP) emulated by `gantry-sim`,
//! brought up by ethercrab, driven by the kernel through gantry's CiA-402 layer every
//! 1 ms cycle. Lockstep: the drives advance one cycle per exchange, so the run is
//! deterministic and needs no real-time thread.

use std::io::Write;
use std::time::Duration;

use crate::ethercat::transition;
use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use gantry_drives::scaling::{Scaling, ScalingConfig};
use gantry_kernel::axis::command::{BufferMode, Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::profile::{Limits, RampType};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_sim::catalog::{self, ServoOptions};
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::record::{write_records, DriveRecord};

use super::{DemoArgs, DemoError, DemoReport};
use crate::drive_records::{judge, AxisBound, Conditions};
use crate::ethercat::cycle::CspCycle;
use crate::ethercat::embedded::EmbeddedBus;
use crate::ethercat::mapping::map_pdos;
use crate::pcap::PcapWriter;
use crate::plot::{self, Panel};
use crate::status_table::{self, Live, Row};
use crate::trace::Trace;
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::csp::CspChannel;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

/// An error of the EtherCAT network at `step`, its cause kept.
fn bus_error<E>(step: impl Into<String>) -> impl FnOnce(E) -> DemoError
where
    E: std::error::Error + Send + Sync + 'static,
{
    let step = step.into();
    move |e| DemoError::Bus {
        step,
        source: Box::new(e),
    }
}

/// 5 mm ball screws on 2^17-count motors.
fn scaling() -> Result<Scaling, DemoError> {
    Scaling::new(ScalingConfig {
        counts_per_motor_rev: 1 << 17,
        motor_revs: 1,
        load_revs: 1,
        units_per_load_rev: 5.0,
        invert: false,
    })
    .map_err(bus_error("scaling"))
}

fn axis(name: &str) -> AxisConfig {
    let mut c = AxisConfig::new(name, AxisKind::Real);
    c.max = Limits {
        vmax: 250.0,
        amax: 2500.0,
        dmax: 2500.0,
        jmax: 50_000.0,
    };
    c.defaults.speed = 150.0;
    c.defaults.acceleration = 1500.0;
    c.defaults.deceleration = 1500.0;
    c.defaults.jerk = 30_000.0;
    c.defaults.ramp = RampType::SCurve;
    c.defaults.target_window = 0.05;
    c
}

/// Runs the EtherCAT demo.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<DemoReport, DemoError> {
    let names = ["x", "y"];
    let chain = SlaveChain::new(
        (0..names.len() as u32)
            .map(|i| {
                catalog::servo(ServoOptions {
                    serial: i + 1,
                    // Absolute encoders: the drives power up away from zero.
                    start_counts: (i as i32) * 300_000,
                    ..ServoOptions::default()
                })
            })
            .collect(),
    );
    let (tx, rx, pdu_loop) = PDU_STORAGE
        .try_split()
        .map_err(|_| DemoError::Network("the EtherCAT demo runs once per process"))?;
    let capture = match &args.pcap {
        Some(path) => {
            let file = std::fs::File::create(path).map_err(|source| DemoError::Io {
                path: path.display().to_string(),
                source,
            })?;
            Some(
                PcapWriter::new(std::io::BufWriter::new(file))
                    .map_err(bus_error(format!("capture to {}", path.display())))?,
            )
        }
        None => None,
    };
    let bus = EmbeddedBus::start_with_capture(tx, rx, chain, capture);
    let chain = bus.chain.clone();
    // The chain runs on lockstep time here: it moves only by each frame's time on the
    // wire, so a busy EEPROM (250 µs) takes dozens of polls, each a round trip between
    // threads. ethercrab's EEPROM timeout is host time (10 ms): give it a loaded host's slack.
    let timeouts = Timeouts {
        eeprom: std::time::Duration::from_millis(500),
        ..Timeouts::default()
    };
    let maindevice = MainDevice::new(pdu_loop, timeouts, MainDeviceConfig::default());
    let dt = args.cycle_s;
    let kernel = Kernel::new(dt, names.iter().map(|n| axis(n)).collect())?;
    // The process data every drive is mapped to in PreOp (by SDO, from this layout).
    let layout = PdoLayout::csp();
    let channel =
        CspChannel::with_layout(scaling()?, &layout).map_err(bus_error("process data layout"))?;
    let mut cycle = CspCycle::new(kernel, vec![channel; names.len()]);
    let mut trace = Trace::new(
        names
            .iter()
            .flat_map(|n| [format!("{n}.set"), format!("{n}.actual")])
            .collect(),
        20_000,
    );
    let mut live = Live::new(false);
    let result = futures_lite::future::block_on(async {
        let group = maindevice
            .init_single_group::<8, 64>(ethercat_now)
            .await
            .map_err(bus_error("scan"))?;
        let _ = writeln!(out, ">> found {} EtherCAT slaves:", group.len());
        for sd in group.iter(&maindevice) {
            let _ = writeln!(
                out,
                "   {:#06x} {} ({})",
                sd.configured_address(),
                sd.name(),
                sd.identity()
            );
        }
        for sd in group.iter(&maindevice) {
            map_pdos(&sd, &layout)
                .await
                .map_err(bus_error("PDO mapping"))?;
        }
        let _ = writeln!(
            out,
            ">> PDOs mapped by SDO: outputs {} B (controlword, target position, mode), inputs {} B (statusword, position, velocity, torque, error code, mode display)",
            layout.output_bytes(),
            layout.input_bytes()
        );
        let group = async {
            let group = group.into_safe_op(&maindevice).await?;
            transition::into_op(group, &maindevice, transition::OP_TIMEOUT).await
        }
        .await
        .map_err(bus_error("to OP"))?;
        let _ = writeln!(out, ">> all slaves in OP; enabling drives (CiA-402)");
        for (i, name) in names.iter().enumerate() {
            cycle
                .kernel
                .command(i, Command::Power(PowerCommand::Enable))
                .map_err(|error| step_error("enable", name, error))?;
        }
        let mut phase = 0;
        let mut handles = Vec::new();
        let mut max_following = [0.0f64; 2];
        for n in 0..60_000u64 {
            for i in 0..names.len() {
                let sd = group
                    .subdevice(&maindevice, i)
                    .map_err(|e| bus_error(format!("cycle {n}: slave {i}"))(e))?;
                cycle
                    .read_inputs(i, &sd.inputs_raw())
                    .map_err(|e| bus_error(format!("cycle {n}: inputs"))(e))?;
            }
            cycle.step();
            let mut sample = Vec::with_capacity(4);
            for (i, following) in max_following.iter_mut().enumerate() {
                let sd = group
                    .subdevice(&maindevice, i)
                    .map_err(|e| bus_error(format!("cycle {n}: slave {i}"))(e))?;
                cycle
                    .write_outputs(i, sd.io_raw_mut().outputs())
                    .map_err(|e| bus_error(format!("cycle {n}: outputs"))(e))?;
                let status = cycle.kernel.axis_status(i).copied().unwrap_or_default();
                sample.push(status.set.p);
                sample.push(status.actual_position);
                if phase >= 2 {
                    *following = following.max((status.set.p - status.actual_position).abs());
                }
            }
            trace.push(cycle.kernel.time(), &sample)?;
            group
                .tx_rx(&maindevice)
                .await
                .map_err(|e| bus_error(format!("cycle {n}"))(e))?;
            if let Ok(mut c) = chain.lock() {
                c.tick(dt);
            }
            // The script: enable, home, move, come back.
            let enabled = (0..names.len()).all(|i| {
                cycle
                    .kernel
                    .axis_status(i)
                    .is_some_and(|s| s.state == gantry_kernel::axis::state::AxisState::Standstill)
            });
            if phase == 0 && enabled {
                let _ = writeln!(
                    out,
                    ">> drives enabled after {n} cycles; homing by SetPosition 0"
                );
                for (i, name) in names.iter().enumerate() {
                    let home = Command::SetPosition {
                        position: 0.0,
                        relative: false,
                    };
                    cycle
                        .kernel
                        .command(i, home)
                        .map_err(|error| step_error("home", name, error))?;
                }
                phase = 1;
            } else if phase == 1 {
                let _ = writeln!(
                    out,
                    ">> x: MovePtp 100 mm then back; y: 60 mm, 20 mm, back (S-curve, buffered)"
                );
                let moves: [(usize, f64, BufferMode); 5] = [
                    (0, 100.0, BufferMode::Aborting),
                    (0, 0.0, BufferMode::Buffered),
                    (1, 60.0, BufferMode::Aborting),
                    (1, 20.0, BufferMode::BlendingNext),
                    (1, 0.0, BufferMode::Buffered),
                ];
                for (axis, to, buffer) in moves {
                    let h = cycle
                        .kernel
                        .command(
                            axis,
                            Command::MovePtp(
                                MovePtp::new(PositioningMode::AbsNormal, to).buffered(buffer),
                            ),
                        )
                        .map_err(|error| step_error("move", names[axis], error))?;
                    handles.push(h);
                }
                phase = 2;
            } else if phase == 2
                && handles
                    .iter()
                    .all(|h| cycle.kernel.command_status(*h).is_final())
            {
                phase = 3;
                let _ = writeln!(out, ">> moves done after {n} cycles");
            } else if phase == 3 {
                break;
            }
            if n % 250 == 0 {
                let rows: Vec<Row> = names
                    .iter()
                    .enumerate()
                    .map(|(i, n)| {
                        let status = cycle.kernel.axis_status(i).copied().unwrap_or_default();
                        Row {
                            axis: (*n).into(),
                            status,
                            command: String::new(),
                            error: status
                                .error
                                .map(|e| crate::axis_fault::describe_fault(&e))
                                .unwrap_or_default(),
                        }
                    })
                    .collect();
                let _ = out.write_all(
                    live.frame(&status_table::render(cycle.kernel.time(), &rows))
                        .as_bytes(),
                );
                if args.speed > 0.0 {
                    std::thread::sleep(Duration::from_secs_f64(0.25 / args.speed));
                }
            }
        }
        for h in &handles {
            if let gantry_kernel::axis::handle::CommandStatus::Error(error) =
                cycle.kernel.command_status(*h)
            {
                return Err(step_error("move", "x/y", error));
            }
        }
        if phase != 3 {
            return Err(DemoError::Timeout("EtherCAT moves"));
        }
        let _ = writeln!(
            out,
            ">> largest following error: x {:.3} mm, y {:.3} mm (drive loop 200 Hz + 2 cycles transport)",
            max_following[0], max_following[1]
        );
        Ok(())
    });
    let frames = bus.stop();
    result?;
    let records = match chain.lock() {
        Ok(c) => c.records(),
        Err(_) => return Err(DemoError::Network("the simulated chain is poisoned")),
    };
    check_drive_invariant(&records, &names, &cycle, dt, out)?;
    let _ = writeln!(
        out,
        ">> {frames} EtherCAT frames exchanged with the simulated drives"
    );
    std::fs::create_dir_all(&args.out).map_err(|source| DemoError::Io {
        path: args.out.display().to_string(),
        source,
    })?;
    // What the drives recorded, for whoever wants to judge the run again.
    write_records(&args.out.join("drive-records.json"), &records)?;
    let csv = args.out.join("ethercat-trace.csv");
    let svg = args.out.join("ethercat-plot.svg");
    trace.write_csv(&csv)?;
    let doc = plot::svg(
        &trace,
        &[Panel {
            title: "set and actual position (mm) over EtherCAT".into(),
            channels: vec![0, 1, 2, 3],
        }],
    );
    std::fs::write(&svg, doc).map_err(|source| DemoError::Io {
        path: svg.display().to_string(),
        source,
    })?;
    Ok(DemoReport {
        csv,
        svg,
        simulated_s: cycle.kernel.time(),
        cycles: cycle.kernel.tick(),
    })
}

/// The drive invariant (issue 10 §6) on what each simulated drive recorded: no target
/// step beyond the axis' `vmax · T` plus one count, no following-error fault, and — the
/// demo runs lockstep, one frame per drive cycle — no missed or doubled setpoint.
fn check_drive_invariant(
    records: &[Option<DriveRecord>],
    names: &[&str],
    cycle: &CspCycle,
    dt: f64,
    out: &mut impl Write,
) -> Result<(), DemoError> {
    let bounds: Vec<AxisBound> = names
        .iter()
        .enumerate()
        .filter_map(|(i, name)| {
            let (channel, axis) = (cycle.channel(i)?, cycle.kernel.axes().get(i)?);
            Some(AxisBound::new(
                name,
                i,
                &channel.scaling,
                axis.config().max.vmax,
                dt,
            ))
        })
        .collect();
    if bounds.len() != names.len() {
        return Err(DemoError::Invariant(format!(
            "{} axes, {} drives in the cycle",
            names.len(),
            bounds.len()
        )));
    }
    let verdict = judge(
        records,
        &bounds,
        Conditions {
            injects_following_error: false,
            phase_locked: true,
        },
    );
    if !verdict.holds() {
        return Err(DemoError::Invariant(verdict.broken.join("; ")));
    }
    let _ = writeln!(
        out,
        ">> drive invariant holds: no following-error fault, no missed or doubled setpoint; {}",
        verdict.summary.join("; ")
    );
    Ok(())
}

fn step_error(
    label: &'static str,
    axis: &'static str,
    error: gantry_kernel::axis::command::CommandError,
) -> DemoError {
    DemoError::Step {
        label,
        axis,
        command: label,
        error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demo_fails_with_the_axis_and_the_rule_when_a_drive_saw_a_step() {
        let kernel = Kernel::new(1e-3, vec![axis("x"), axis("y")]).unwrap();
        let channel = CspChannel::new(scaling().unwrap());
        let cycle = CspCycle::new(kernel, vec![channel.clone(), channel]);
        // 250 mm/s at 2^17 counts per 5 mm: 6553.6 counts per ms, bound 6554.
        let mut ok = DriveRecord::default();
        ok.target(0);
        ok.target(6554);
        let mut step = ok;
        step.target(6554 + 6555);
        let mut text = Vec::new();
        check_drive_invariant(&[Some(ok), Some(ok)], &["x", "y"], &cycle, 1e-3, &mut text).unwrap();
        let text = String::from_utf8(text).unwrap();
        assert!(
            text.contains("x: largest target step 6554 counts (bound 6554), 2 targets"),
            "{text}"
        );
        let e = check_drive_invariant(
            &[Some(ok), Some(step)],
            &["x", "y"],
            &cycle,
            1e-3,
            &mut Vec::new(),
        )
        .unwrap_err();
        assert!(
            e.to_string().starts_with(
                "drive invariant broken: axis y (drive 1): target stepped 6555 counts in one \
                 cycle at target #2; vmax · T + 1 count is 6554; DriveRecord {"
            ),
            "{e}"
        );
        let e = check_drive_invariant(&[Some(ok)], &["x", "y"], &cycle, 1e-3, &mut Vec::new())
            .unwrap_err();
        assert!(
            e.to_string()
                .contains("axis y (drive 1): no drive record at that chain position"),
            "{e}"
        );
    }
}
