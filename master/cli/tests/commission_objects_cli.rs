//! `gantry commission x commutation` on a drive whose maker put the commutation objects
//! elsewhere than gantry-sim's default (0x2100–0x2103, mode −1), through the binary: the
//! simulated servo has them at 0x3010 (offset, in tenths of an electrical degree), 0x3012
//! (current) and 0x3013 (angle, in tenths of a degree), open-loop mode −3, and no pole pairs
//! object; `[axis.commutation]` names them and the pole pairs.
//!
//! Without `[axis.commutation]` the measurement is refused by the drive, naming the object
//! it lacks. With it, the offset is measured within ±1° electrical of the hidden one,
//! written to 0x3010 in the drive's units, saved in counts, and written back in the drive's
//! units at the next start of master and simulator.

mod support;

use gantry_drives::commutation::electrical_error_deg;
use support::Service;

/// The simulated motor of `x`: 2¹⁷ counts, 5 pole pairs (the simulator's defaults), its
/// true commutation offset 21 000 counts (288.4° electrical from the drive's 0).
const COUNTS_PER_REV: u32 = 1 << 17;
const POLE_PAIRS: u32 = 5;
const HIDDEN_OFFSET: i64 = 21_000;
/// Tenths of a degree to an electrical revolution.
const TENTHS: i64 = 3600;

/// The other maker's objects, as the simulated servo has them.
const SIM_OBJECTS: &str = "commutation = { mode = -3, offset = 0x3010, offset_units = 3600, \
     pole_pairs = 0, current = 0x3012, angle = 0x3013, angle_units = 3600 }";
/// The same as `[axis.commutation]` names them.
const AXIS_OBJECTS: &str = "commutation = { mode = -3, offset = { index = 0x3010 }, \
     offset_units = 3600, pole_pairs = 5, current = { index = 0x3012 }, \
     angle = { index = 0x3013 }, angle_units = 3600 }";

fn state_dir() -> std::path::PathBuf {
    std::env::temp_dir().join(format!(
        "gantry-state-commission-objects-{}",
        std::process::id()
    ))
}

/// The example with `x`'s drive built by the other maker; `axis` lines added to `x`.
fn start(tag: &str, axis: &str) -> Service {
    let axes = "# One [[axis]] per drive.";
    let x_pdo = "pdo = \"csp\"                   # mapped by SDO in PreOp";
    let axis = axis.to_string();
    let config = move |c: String| {
        assert!(c.contains(axes) && c.contains(x_pdo), "the example changed");
        let service = format!("[service]\nstate_dir = {:?}\n\n{axes}", state_dir());
        // Not real time (`--no-rt`): overruns on a loaded host are not the claim here.
        let overruns = "overrun_limit = 10 ";
        assert!(c.contains(overruns));
        c.replacen(axes, &service, 1)
            .replacen(overruns, "overrun_limit = 1000 ", 1)
            .replacen(x_pdo, &format!("{axis}\n{x_pdo}"), 1)
    };
    Service::start_edited(tag, config, |chain| {
        let first = "[[slave]]\nkind = \"servo\"\n";
        assert!(chain.contains(first));
        // Not real time (`--no-rt`): the drives ride through the host's stalls.
        let chain = chain.replace("sync_error_limit = 32", "sync_error_limit = 1000");
        chain.replacen(
            first,
            &format!("{first}commutation_offset = {HIDDEN_OFFSET}\n{SIM_OBJECTS}\n"),
            1,
        )
    })
}

/// The drive's 0x3010 (tenths of an electrical degree).
fn drive_offset(svc: &Service) -> i64 {
    svc.ok(&["sdo", "upload", "--axis", "x", "0x3010:0", "--type", "i32"])
        .trim()
        .parse()
        .unwrap()
}

#[test]
fn another_maker_s_commutation_objects_are_used_as_configured() {
    let _ = std::fs::remove_dir_all(state_dir());
    // Not configured: gantry asks for gantry-sim's default 0x2101, which this drive lacks.
    let svc = start("commission-objects-default", "");
    let e = svc.fails(&["commission", "x", "commutation"]);
    assert!(e.contains("x: ") && e.contains("0x2101"), "{e}");
    assert!(
        e.contains("0x06020000") || e.contains("does not exist"),
        "{e}"
    );
    assert_eq!(drive_offset(&svc), 0, "nothing written");
    drop(svc);

    // Configured: measured through 0x3012/0x3013 in mode -3, written to 0x3010.
    let mut svc = start("commission-objects", AXIS_OBJECTS);
    let out = svc.commission_commutation("x");
    let tenths = drive_offset(&svc);
    assert!((0..TENTHS).contains(&tenths), "{tenths}");
    let e = i64::from(COUNTS_PER_REV) / i64::from(POLE_PAIRS);
    let counts = (tenths as f64 / TENTHS as f64 * e as f64).round() as i64;
    let miss = electrical_error_deg(counts, HIDDEN_OFFSET, COUNTS_PER_REV, POLE_PAIRS);
    assert!(
        miss.abs() <= 1.0,
        "0x3010 = {tenths}: {miss}° electrical off"
    );
    // Reported and saved in counts (within the drive's rounding to a tenth of a degree).
    let reported: i64 = out
        .split("offset ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no offset in {out}"));
    assert!(
        (reported - counts).abs() <= 4,
        "{reported} vs {counts}: {out}"
    );
    let text = std::fs::read_to_string(state_dir().join("x.params")).unwrap();
    assert!(
        text.contains(&format!("commutation_offset = {reported}")),
        "{text}"
    );
    // The open-loop mode is left, the current off; enabled, the motor holds and moves.
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "x", "0x3012:0", "--type", "u16"])
            .trim(),
        "0"
    );
    svc.ok(&["enable", "x"]);
    svc.ok(&["set-position", "x", "--position", "0"]);
    svc.ok(&["move", "x", "--to", "2", "--speed", "10"]);
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    drop(svc);

    // Master and simulator again: the saved offset goes back in tenths of a degree.
    let mut svc = start("commission-objects-restart", AXIS_OBJECTS);
    assert_eq!(drive_offset(&svc), tenths);
    svc.ok(&["enable", "x"]);
    svc.ok(&["set-position", "x", "--position", "0"]);
    svc.ok(&["move", "x", "--to", "1", "--speed", "10"]);
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    assert!(
        out.contains(&format!(
            "axis x: commutation offset {reported} counts written to its drive (0x3010:00)"
        )),
        "{out}"
    );
    let _ = std::fs::remove_dir_all(state_dir());
}
