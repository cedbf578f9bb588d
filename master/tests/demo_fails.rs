//! `gantry demo` fails, with what and why, when a drive faults: the demo on a chain whose
//! rotary drive cannot follow (a 10 Hz velocity loop, a following-error window of 100
//! counts, 0x6065) stops at that drive's following-error fault instead of running on, and
//! still writes the drives' records. Its own process: the EtherCAT bus starts once per
//! process.

use gantry::demo::ethercat::{run_on, SERVOS_TOML};
use gantry::demo::{DemoArgs, DemoError};

#[test]
fn the_demo_stops_at_a_drive_fault_and_says_which_axis_and_why() {
    let dir = std::env::temp_dir().join(format!("gantry-demo-fails-{}", std::process::id()));
    // The third servo (axis c) made slow and strict.
    let at = SERVOS_TOML
        .find("start_position = -1000000")
        .expect("c's servo");
    let servos = format!(
        "{}following_error_window = 100\nbandwidth_hz = 10\n{}",
        &SERVOS_TOML[..at],
        &SERVOS_TOML[at..]
    );
    let args = DemoArgs {
        out: dir.clone(),
        speed: 0.0,
        ..DemoArgs::default()
    };
    let mut log = Vec::new();
    let e = run_on(&args, &servos, &mut log).expect_err("a drive faulted");
    let log = String::from_utf8(log).unwrap();
    assert!(matches!(e, DemoError::Fault(_)), "{e:?}");
    assert!(
        e.to_string().starts_with(
            "the demo stopped: axis c in ErrorStop: drive fault 0x8611: following error"
        ),
        "{e}\n{log}"
    );
    // The bus went down cleanly, the figures were printed, the records say the same.
    assert!(log.contains("bus: slaves in PreOp"), "{log}");
    assert!(log.contains(">> cycles: "), "{log}");
    let records: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("drive-records.json")).unwrap()).unwrap();
    assert_eq!(records[2]["last_fault_code"], 0x8611, "{records}");
    assert!(
        records[2]["following_error_faults"].as_u64().unwrap() >= 1,
        "{records}"
    );
    assert_eq!(records[0]["faults"], 0, "{records}");
    std::fs::remove_dir_all(&dir).unwrap();
}
