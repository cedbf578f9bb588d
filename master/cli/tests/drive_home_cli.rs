//! `gantry home AXIS --drive` end to end, through the binary: `gantry run --no-rt` on the
//! example configuration with `[axis.drive_homing]` on axis `x` and switch cams on its
//! simulated servo; the drive homes itself (CiA 402 homing mode, method 19: the home
//! switch's positive edge), is handed back in CSP and the axis is homed reading minus the
//! home offset; a method the drive does not have is refused with the drive's SDO abort,
//! and a MoveHome option with --drive is refused by name.

mod support;

use support::Service;

/// The home cam of the first servo (counts): 10 mm to just under 12 mm.
const CAM: (i64, i64) = (262_144, 314_572);

#[test]
fn gantry_home_drive_lets_the_drive_home_itself_from_the_shell() {
    let svc = Service::start_edited(
        "drive-home",
        |config| {
            let x = "pdo = \"csp\"                   # mapped by SDO in PreOp: + velocity, torque, error code";
            assert!(config.contains(x), "the example maps x with csp");
            config.replacen(
                x,
                "pdo = \"csp\"\ndrive_homing = { method = 19, speed_switch = 20.0, \
                 speed_zero = 2.0, acceleration = 200.0, home_offset = 2.0, timeout = 20.0 }",
                1,
            )
        },
        |chain| {
            let first = "[[slave]]\nkind = \"servo\"\n";
            assert!(chain.contains(first));
            let chain = chain.replace("sync_error_limit = 32", "sync_error_limit = 1000");
            chain.replacen(
                first,
                &format!(
                    "{first}[slave.switches]\nnegative_limit = [-9000000000, -1310720]\n\
                     positive_limit = [13107200, 9000000000]\nhome = [{}, {}]\n",
                    CAM.0, CAM.1
                ),
                1,
            )
        },
    );
    svc.ok(&["enable", "x"]);
    let e = svc.fails(&["home", "x", "--drive", "--jerk", "5"]);
    assert!(e.contains("--jerk is a MoveHome option"), "{e}");
    let e = svc.fails(&["home", "x", "--drive", "--method", "15"]);
    assert!(
        e.contains(
            "x: drive homing method 15: the drive refused 0x6098:00 = 15 (SDO abort 0x06090030"
        ),
        "{e}"
    );
    // From below the cam: method 19 stops on its positive edge, which reads -2 mm.
    let out = svc.ok(&["home", "x", "--drive"]);
    assert!(
        out.contains("x: homed by its drive; stands at -2.000"),
        "{out}"
    );
    let x = svc.axis("x");
    assert_eq!(x["homed"], true, "{x}");
    assert_eq!(x["state"], "Standstill", "{x}");
    let status = svc.status();
    let drive = &status["drives"][0];
    assert_eq!(drive["mode"], 8, "back in CSP: {drive}");
    assert!(drive["procedure"].is_null(), "{drive}");
    // The axis moves in the homed frame.
    svc.ok(&["move", "x", "--to", "5", "--speed", "20"]);
    let p = svc.axis("x")["position"].as_f64().unwrap();
    assert!((p - 5.0).abs() < 0.01, "{p}");
    // Progress in `gantry status`: started without waiting from 7 mm below the edge
    // (3.5 s of search at 2 mm/s), the drive's line names the procedure and its phase.
    svc.ok(&["move", "x", "--to=-9", "--speed", "50"]);
    svc.ok(&["home", "x", "--drive", "--speed-switch", "2", "--no-wait"]);
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    let mut seen = None;
    while std::time::Instant::now() < deadline {
        let table = svc.ok(&["status"]);
        if let Some(line) = table
            .lines()
            .find(|l| l.starts_with("x ") && l.contains("drive homing method 19: "))
        {
            seen = Some(line.to_string());
            break;
        }
    }
    let line = seen.expect("the procedure in the status table");
    assert!(
        line.contains("homing") || line.contains("writing"),
        "{line}"
    );
    while std::time::Instant::now() < deadline && svc.axis("x")["state"] != "Standstill" {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let x = svc.axis("x");
    assert_eq!(x["homed"], true, "{x}");
    assert!((x["position"].as_f64().unwrap() + 2.0).abs() < 0.001, "{x}");
}
