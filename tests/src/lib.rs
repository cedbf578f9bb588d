//! End-to-end tests of gantry: the master and the simulator together. The tests live in
//! `tests/tests/`; what they share lives here, in the master (`gantry::ethercat`) and in the binary's
//! in-process simulator (`gantry_cli::simulator`, `gantry_cli::embedded`).

pub mod can;
pub mod can_lockfree;
pub mod can_rig;
pub mod cyclic_frame;
pub mod dc_phase;
pub mod drive_counts;
pub mod drive_homing;
pub mod homing;
pub mod homing_matrix;
pub mod invariant;
pub mod lockstep;
pub mod netns;
pub mod rig;
pub mod seccomp;
pub mod servo_rig;
pub mod slave_loss;
pub mod threads;

pub use gantry_cli::embedded::EmbeddedBus;

use gantry_drives::scaling::{Scaling, ScalingConfig};

/// The axis the end-to-end tests drive: a 5 mm ball screw on a 2^17-count motor.
pub fn ball_screw_5mm() -> Scaling {
    Scaling::new(ScalingConfig {
        counts_per_motor_rev: 1 << 17,
        motor_revs: 1,
        load_revs: 1,
        units_per_load_rev: 5.0,
        invert: false,
    })
    .expect("a valid scaling")
}

/// ethercrab's timeouts for a chain on lockstep time (`EmbeddedBus::start`, [`lockstep`]).
/// There the chain's time moves only by each frame's time on the wire, so a device that
/// is busy for a while (an EEPROM read: 250 µs of chain time, ~37 polls) is polled by
/// dozens of frames, each a round trip between threads on the host. ethercrab's timeouts
/// are host time: its EEPROM one (10 ms, sized for a real network's microsecond round
/// trips) gets the slack of a loaded host; the others stay as they are.
pub fn lockstep_timeouts() -> ethercrab::Timeouts {
    ethercrab::Timeouts {
        eeprom: std::time::Duration::from_millis(500),
        ..ethercrab::Timeouts::default()
    }
}

/// A chain of `n` catalog servos with serial numbers 1…n.
pub fn servo_chain(n: u32) -> gantry_sim::chain::SlaveChain {
    use gantry_sim::catalog::{self, ServoOptions};
    gantry_sim::chain::SlaveChain::new(
        (1..=n)
            .map(|serial| {
                catalog::servo(ServoOptions {
                    serial,
                    ..ServoOptions::default()
                })
            })
            .collect(),
    )
}

/// 0x10F1:02 for simulated drives that run on a host without real time: about ten
/// missed periods in a row before a sync error (the standard default, 4, is two).
pub const STALL_TOLERANT_SYNC_ERROR_LIMIT: u16 = 32;

/// 0x10F1:02 as drives ship it.
pub use gantry_sim::esc::al::DEFAULT_SYNC_ERROR_LIMIT;

/// A configuration of `axes` axes on simulated servos in this process (`[bus] simulator`),
/// at `cycle_us`; the simulator's chain file is written to a temporary folder.
pub fn sim_config(axes: usize, cycle_us: u32) -> gantry::config::Config {
    sim_config_with(axes, cycle_us, "")
}

/// As [`sim_config`], with the drives as strict as they come (0x10F1:02 = 4: two missed
/// SYNC0 periods in a row take a drive out of Op): for the lockstep [`rig::Rig`], whose
/// master is never late.
pub fn sim_config_strict(axes: usize, cycle_us: u32) -> gantry::config::Config {
    sim_config_with(
        axes,
        cycle_us,
        &format!("[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}"),
    )
}

/// As [`sim_config`], with `servo` (TOML keys, e.g. `dc_drift_ppm = 300`) added to every
/// simulated servo.
pub fn sim_config_with(axes: usize, cycle_us: u32, servo: &str) -> gantry::config::Config {
    // The real-time tests run the simulator on the host's clock, on shared machines
    // without PREEMPT_RT whose threads stall for milliseconds now and then (the lockstep
    // rig's tests take `sim_config_strict`: their master is never late). A DC drive counts each
    // SYNC0 period without a setpoint (+3, -1 per setpoint; 0x10F1:02 = 4 by default:
    // two periods in a row take it out of Op, as on real drives): these drives are set to
    // ride through a stall of about ten periods. The strict default is what the lockstep
    // tests (`lockstep_sync0_phase`, the drive invariant) hold the master to.
    // A `servo` that opens `[slave.al]` itself gets the key in its table, unless it sets it.
    let limit = format!("sync_error_limit = {STALL_TOLERANT_SYNC_ERROR_LIMIT}");
    let al = match (
        servo.contains("[slave.al]"),
        servo.contains("sync_error_limit"),
    ) {
        (_, true) => String::new(),
        (true, false) => limit,
        (false, false) => format!("[slave.al]\n{limit}"),
    };
    let chain: String = (0..axes)
        .map(|_| format!("[[slave]]\nkind = \"servo\"\n{servo}\n{al}\n"))
        .collect();
    let axes: String = (0..axes)
        .map(|i| {
            format!(
                "[[axis]]\nname = \"a{i}\"\ndrive = {i}\n\
                 scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
                 max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n"
            )
        })
        .collect();
    sim_config_text(cycle_us, &chain, "", &axes)
}

/// A configuration at `cycle_us` whose bus is the simulator's chain `slaves` (its
/// `[[slave]]` tables, as `gantry_sim::config` reads them), with `bus` (more `[bus]` keys,
/// e.g. `dc = false`), and whose axes are `axes` (gantry's `[[axis]]` tables), for a test that needs drives or axes of its own (start counts, servo
/// tuning, I/O modules; scaling, modulo, limits, target monitoring). The simulator's file
/// is written to a temporary folder, one file per call: tests of one binary run in
/// parallel and each must read its own chain.
pub fn sim_config_text(
    cycle_us: u32,
    slaves: &str,
    bus: &str,
    axes: &str,
) -> gantry::config::Config {
    static FILES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!("gantry-sim-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let n = FILES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let sim = dir.join(format!("sim-{n}.toml"));
    std::fs::write(&sim, format!("cycle_us = {cycle_us}\n{slaves}")).expect("sim.toml");
    let text = format!(
        "[bus]\nkind = \"ethercat\"\nsimulator = {:?}\ncycle_us = {cycle_us}\n{bus}\n{axes}",
        sim.display().to_string()
    );
    gantry::config::Config::parse(&text, "test.toml")
        .unwrap_or_else(|e| panic!("a valid test configuration: {e}\n{text}"))
}

/// A device without a mailbox whose process data the EEPROM describes (one RxPDO 0x1600
/// on SM2 at 0x1100, one TxPDO 0x1A00 on SM3 at 0x1400), as simple terminals have:
/// `outputs` and `inputs` list (object index, bits), sub-index 0.
pub fn eeprom_pdo_device(
    serial: u32,
    outputs: &[(u16, u8)],
    inputs: &[(u16, u8)],
) -> gantry_sim::esc::sii::DeviceDescription {
    use gantry_sim::esc::sii::{DeviceDescription, PdoDescription, PdoEntry, SmDescription};
    let pdo = |index, sync_manager, entries: &[(u16, u8)]| PdoDescription {
        index,
        sync_manager,
        entries: entries
            .iter()
            .map(|&(index, bits)| PdoEntry {
                index,
                sub: 0,
                bits,
            })
            .collect(),
    };
    let sm = |start, control, kind| SmDescription {
        start,
        length: 0,
        control,
        enable: true,
        kind,
    };
    DeviceDescription {
        vendor_id: gantry_sim::catalog::VENDOR_ID,
        product_code: 0x0402,
        revision: 1,
        serial,
        order_code: "SIM-IO".into(),
        name: "sim I/O".into(),
        mailbox: None,
        mailbox_protocols: 0,
        sync_managers: vec![
            sm(gantry_sim::catalog::OUTPUTS_AT, 0x64, 3),
            sm(gantry_sim::catalog::INPUTS_AT, 0x20, 4),
        ],
        fmmus: vec![1, 2],
        dc: false,
        rx_pdos: vec![pdo(0x1600, 0, outputs)],
        tx_pdos: vec![pdo(0x1A00, 1, inputs)],
    }
}
