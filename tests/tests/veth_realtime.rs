//! Real time, two processes: the master in this process and `gantry-sim` as its own
//! process, on the two ends of a veth pair in two network namespaces. Four CiA-402
//! servos at 1 kHz for 10 s, each moving back and forth the whole time; the test reports
//! the cycle figures (wake-up latency, compute, bus round trip) and checks that every
//! frame came back with the right working counter and every move finished.
//!
//! Needs root for the namespaces; `deploy/test.sh` runs it (`--include-ignored`).

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use gantry::ethercat::cycle::CspCycle;
use gantry::ethercat::cyclic::CspChannel;
use gantry::ethercat::raw::RawBus;
use gantry::ethercat::transition;
use gantry::runtime::clock::{now_ns, CycleClock};
use gantry::runtime::histogram::{Histogram, Summary};
use gantry_kernel::axis::command::{
    Command as AxisCommand, MovePtp, PositioningMode, PowerCommand,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::profile::{Limits, RampType};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_tests::ball_screw_5mm;
use gantry_tests::netns::{start_gantry_sim, VethPair};

const DRIVES: usize = 4;
const CYCLES: u64 = 10_000;
const PERIOD_NS: u64 = 1_000_000;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

const SIM_CONFIG: &str = r#"
cycle_us = 1000
[[slave]]
kind = "servo"
[[slave]]
kind = "servo"
start_position = 100000
[[slave]]
kind = "servo"
start_position = -250000
[[slave]]
kind = "servo"
bandwidth_hz = 150
"#;

fn axis(i: usize) -> AxisConfig {
    let mut c = AxisConfig::new(&format!("a{i}"), AxisKind::Real);
    c.max = Limits {
        vmax: 250.0,
        amax: 2500.0,
        dmax: 2500.0,
        jmax: 50_000.0,
    };
    c.defaults.speed = 200.0;
    c.defaults.acceleration = 2000.0;
    c.defaults.deceleration = 2000.0;
    c.defaults.jerk = 40_000.0;
    c.defaults.ramp = RampType::SCurve;
    c
}

#[derive(Debug, Default)]
struct Report {
    wake: Summary,
    compute: Summary,
    round_trip: Summary,
    overruns: u64,
    bus_errors: u64,
    wkc_errors: u64,
    expected_wkc: u16,
    moves_done: [u32; DRIVES],
    max_following_mm: f64,
    enabled_after: u64,
    realtime: String,
}

/// SCHED_FIFO for this thread (threads it creates, like the frame pump, inherit it).
fn realtime(priority: u8) -> String {
    use thread_priority::*;
    let p = ThreadPriority::Crossplatform(priority.try_into().unwrap());
    match set_thread_priority_and_policy(
        thread_native_id(),
        p,
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    ) {
        Ok(()) => format!("SCHED_FIFO {priority}"),
        Err(e) => format!("not real time ({e:?})"),
    }
}

fn run_master(pair: &VethPair) -> Result<Report, String> {
    pair.enter_master_ns()?;
    let mut report = Report {
        realtime: realtime(80),
        ..Report::default()
    };
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().map_err(|_| "PDU storage")?;
    let bus = RawBus::open(&pair.master_if, tx, rx, None).map_err(|e| e.to_string())?;
    let md = MainDevice::new(pdu_loop, Timeouts::default(), MainDeviceConfig::default());
    let result = futures_lite::future::block_on(async {
        let group = md
            .init_single_group::<8, 128>(ethercat_now)
            .await
            .map_err(|e| format!("scan: {e}"))?;
        if group.len() != DRIVES {
            return Err(format!("found {} slaves, expected {DRIVES}", group.len()));
        }
        let group = async {
            let group = group.into_safe_op(&md).await?;
            transition::into_op(group, &md, transition::OP_TIMEOUT).await
        }
        .await
        .map_err(|e| format!("to OP: {e}"))?;
        let kernel =
            Kernel::new(1e-3, (0..DRIVES).map(axis).collect()).map_err(|e| e.to_string())?;
        let mut cycle = CspCycle::new(kernel, vec![CspChannel::new(ball_screw_5mm()); DRIVES]);
        for i in 0..DRIVES {
            cycle
                .kernel
                .command(i, AxisCommand::Power(PowerCommand::Enable))
                .map_err(|e| e.to_string())?;
        }
        // LRW: each slave with inputs and outputs counts 3.
        report.expected_wkc = 3 * DRIVES as u16;
        let (mut wake, mut compute, mut rtt) = (
            Histogram::new(10_000),
            Histogram::new(10_000),
            Histogram::new(10_000),
        );
        let mut moves: [Option<_>; DRIVES] = [None; DRIVES];
        let mut homed = [false; DRIVES];
        let mut clock = CycleClock::start(PERIOD_NS);
        for n in 0..CYCLES {
            let w = clock.wait();
            wake.record(w.latency_ns);
            report.overruns += u64::from(w.overrun);
            let t0 = now_ns();
            for i in 0..DRIVES {
                let sd = group.subdevice(&md, i).map_err(|e| e.to_string())?;
                cycle
                    .read_inputs(i, &sd.inputs_raw())
                    .map_err(|e| e.to_string())?;
            }
            cycle.step();
            for i in 0..DRIVES {
                let sd = group.subdevice(&md, i).map_err(|e| e.to_string())?;
                cycle
                    .write_outputs(i, sd.io_raw_mut().outputs())
                    .map_err(|e| e.to_string())?;
                let s = *cycle.kernel.axis_status(i).ok_or("status")?;
                if let Some(h) = moves[i] {
                    report.max_following_mm = report
                        .max_following_mm
                        .max((s.set.p - s.actual_position).abs());
                    match cycle.kernel.command_status(h) {
                        CommandStatus::Done => {
                            report.moves_done[i] += 1;
                            moves[i] = None;
                        }
                        CommandStatus::Error(e) => return Err(format!("axis {i}: {e}")),
                        CommandStatus::Aborted => return Err(format!("axis {i}: move aborted")),
                        _ => {}
                    }
                }
                if moves[i].is_none() && s.state == AxisState::Standstill {
                    if !homed[i] {
                        // The absolute encoders power up anywhere: call here 0.
                        report.enabled_after = report.enabled_after.max(n);
                        let home = AxisCommand::SetPosition {
                            position: 0.0,
                            relative: false,
                        };
                        cycle.kernel.command(i, home).map_err(|e| e.to_string())?;
                        homed[i] = true;
                        continue;
                    }
                    let to = if report.moves_done[i] % 2 == 0 {
                        20.0 + 5.0 * i as f64
                    } else {
                        -10.0
                    };
                    let h = cycle
                        .kernel
                        .command(
                            i,
                            AxisCommand::MovePtp(MovePtp::new(PositioningMode::AbsNormal, to)),
                        )
                        .map_err(|e| e.to_string())?;
                    moves[i] = Some(h);
                }
            }
            let t1 = now_ns();
            compute.record(t1 - t0);
            match group.tx_rx(&md).await {
                Ok(r) if r.working_counter != report.expected_wkc => report.wkc_errors += 1,
                Ok(_) => {}
                Err(_) => report.bus_errors += 1,
            }
            rtt.record(now_ns() - t1);
        }
        report.wake = wake.summary();
        report.compute = compute.summary();
        report.round_trip = rtt.summary();
        Ok(report)
    });
    bus.stop();
    result
}

#[test]
#[ignore = "needs root (network namespaces) and the gantry-sim binary; deploy/test.sh runs it"]
fn four_drives_at_1khz_for_10_s_over_veth() {
    let pair = VethPair::create("rt").expect("veth pair in two namespaces");
    let dir = std::env::temp_dir().join(format!("gantry-veth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("sim.toml");
    std::fs::write(&config, SIM_CONFIG).unwrap();
    let sim = start_gantry_sim(&pair.sim_ns, &pair.sim_if, &config, 4);

    let report = std::thread::scope(|s| s.spawn(|| run_master(&pair)).join().unwrap());
    drop(sim);
    std::fs::remove_dir_all(&dir).unwrap();
    let report = report.unwrap();
    eprintln!(
        "veth, {DRIVES} drives, 1 kHz, {CYCLES} cycles, master {}:\n  wake-up latency {}\n  compute         {}\n  bus round trip  {}\n  overruns {}, lost frames {}, wrong working counters {} (expected {})\n  moves done {:?}, largest following error {:.3} mm, drives enabled after {} cycles",
        report.realtime,
        report.wake,
        report.compute,
        report.round_trip,
        report.overruns,
        report.bus_errors,
        report.wkc_errors,
        report.expected_wkc,
        report.moves_done,
        report.max_following_mm,
        report.enabled_after,
    );
    // Generous bounds: this runs on shared, software-emulated CI machines. The figures
    // above are the result; these only catch a broken exchange.
    assert_eq!(report.bus_errors, 0, "every frame came back");
    assert_eq!(report.wkc_errors, 0, "every working counter was right");
    for (i, done) in report.moves_done.iter().enumerate() {
        assert!(*done >= 10, "axis {i} moved back and forth: {done} moves");
    }
    // 0.3–1 mm in a quiet run (servo lag plus a cycle's transport at 200 mm/s); a stall of
    // the simulator's process longer than four periods skips plant time (as the ESC's
    // application would miss cycles), so this VM's 5–10 ms stalls can add a few mm. A
    // broken exchange (wrong or stale setpoints) gives tens.
    assert!(report.max_following_mm < 5.0, "drives followed: {report:?}");
    assert!(
        report.overruns < CYCLES / 4,
        "the cycle mostly kept its deadline: {report:?}"
    );
}
