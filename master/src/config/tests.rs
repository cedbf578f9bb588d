use super::*;

const EXAMPLE: &str = include_str!("../../../deploy/examples/veth-4-axes.toml");

#[test]
fn the_shipped_example_is_valid() {
    let c = Config::parse(EXAMPLE, "veth-4-axes.toml").unwrap();
    assert_eq!(c.axes.len(), 4);
    assert_eq!(c.bus.cycle_us, 1000);
    assert_eq!(c.kernel_axes[0].defaults.speed, 100.0);
    assert_eq!(
        c.kernel_axes[1].defaults.speed, 250.0,
        "defaults are the maxima"
    );
    assert!(c.kernel_axes[3].mechanics.modulo.is_some());
    assert_eq!(c.rt.priority, 80);
}

/// The example with `old` replaced by `new`, parsed; the error text.
fn mistake(old: &str, new: &str) -> String {
    assert!(EXAMPLE.contains(old), "{old}");
    Config::parse(&EXAMPLE.replacen(old, new, 1), "g.toml")
        .unwrap_err()
        .to_string()
}

fn line_of(needle: &str) -> usize {
    EXAMPLE.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn the_simulator_record_is_relative_to_the_configuration() {
    let dir = std::env::temp_dir().join(format!("gantry-config-record-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let example = include_str!("../../../deploy/examples/sim-4-axes.toml");
    assert!(example.contains("# simulator_record = \"drive-records.json\""));
    let text = example.replace(
        "# simulator_record = \"drive-records.json\"",
        "simulator_record = \"drive-records.json\"",
    );
    let path = dir.join("g.toml");
    std::fs::write(&path, text).unwrap();
    let c = Config::load(&path.display().to_string()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(
        c.bus.simulator_record,
        Some(dir.join("drive-records.json").display().to_string())
    );
}

#[test]
fn every_mistake_names_file_line_key_and_reason() {
    // Unknown key: its own line.
    let l = line_of("lock_memory = true");
    assert_eq!(
        mistake("lock_memory = true", "lock_memroy = true"),
        format!("g.toml:{l}: lock_memroy: unknown field `lock_memroy`, expected one of `priority`, `cpu`, `lock_memory`, `overrun_limit`")
    );
    // Wrong type.
    let l = line_of("cycle_us = 1000");
    let e = mistake("cycle_us = 1000", "cycle_us = \"1ms\"");
    assert_eq!(
        e,
        format!("g.toml:{l}: cycle_us: invalid type: string \"1ms\", expected u32")
    );
    // Inconsistent limits: a default above the maximum, at the key's line.
    let l = line_of("speed = 100.0");
    assert_eq!(
        mistake("speed = 100.0", "speed = 300.0"),
        format!(
            "g.toml:{l}: axis[0].defaults.speed: defaults.speed = 300 exceeds the axis maximum 250"
        )
    );
    // A value out of range.
    let l = line_of("cycle_us = 1000");
    assert_eq!(
        mistake("cycle_us = 1000", "cycle_us = 100"),
        format!("g.toml:{l}: bus.cycle_us: 100 µs is outside 250 to 4000 µs")
    );
    // Two axes on one drive.
    let l = line_of("drive = 1");
    assert_eq!(
        mistake("drive = 1", "drive = 0"),
        format!("g.toml:{l}: axis[1].drive: drive 0 is also axis[0]'s")
    );
    // A ramp that does not exist.
    assert!(mistake("ramp = \"scurve\"", "ramp = \"s\"")
        .ends_with("axis[0].defaults.ramp: \"s\" is not scurve, trapezoid, sine or linear-sine"));
    // Missing key.
    let e = mistake("kind = \"ethercat\"\n", "");
    assert!(e.contains("missing field `kind`"), "{e}");
    // Scaling that cannot be.
    let e = mistake(
        "units_per_load_rev = 5.0      # ball screw lead",
        "units_per_load_rev = 0.0",
    );
    assert!(e.contains("axis[0].scaling:"), "{e}");
    // Records of simulated drives on a real network.
    let l = line_of("cycle_us = 1000");
    let e = mistake(
        "cycle_us = 1000",
        "cycle_us = 1000\nsimulator_record = \"r.json\"",
    );
    assert!(
        e.starts_with(&format!(
            "g.toml:{}: bus.simulator_record: records what simulated drives saw: give it with \
             simulator = \"sim.toml\"",
            l + 1
        )),
        "{e}"
    );
    // Both interface and simulator.
    let e = mistake(
        "cycle_us = 1000",
        "cycle_us = 1000\nsimulator = \"sim.toml\"",
    );
    assert!(
        e.contains("bus.simulator: give either interface or simulator, not both"),
        "{e}"
    );
}

#[test]
fn target_monitoring_is_read_defaults_to_on_and_its_mistakes_are_named() {
    let c = Config::parse(EXAMPLE, "veth-4-axes.toml").unwrap();
    let x = c.kernel_axes[0].target_monitoring;
    assert!(x.enabled);
    assert_eq!((x.dwell_s, x.timeout_s), (0.02, 5.0));
    // y gives no section: on, with the kernel's defaults.
    assert_eq!(
        c.kernel_axes[1].target_monitoring,
        gantry_kernel::axis::TargetMonitoring::new(true)
    );
    let off = Config::parse(
        &EXAMPLE.replacen("enabled = true ", "enabled = false", 1),
        "g.toml",
    )
    .unwrap();
    assert!(!off.kernel_axes[0].target_monitoring.enabled);
    let e = mistake("dwell_s = 0.02 ", "dwell_s = 5.0  ");
    assert!(
        e.contains("axis[0].target_monitoring: dwell_s = 5 and timeout_s = 5"),
        "{e}"
    );
}

#[test]
fn an_unreadable_file_is_named_with_why() {
    let e = Config::load("/nonexistent-gantry/g.toml").unwrap_err();
    assert_eq!(e.to_string(), "cannot read /nonexistent-gantry/g.toml");
    let why = std::error::Error::source(&e).map(|s| s.to_string());
    assert!(
        why.as_deref()
            .is_some_and(|w| w.starts_with("No such file or directory")),
        "{why:?}"
    );
}

#[test]
fn switches_add_their_objects_to_the_layout_and_name_their_mistakes() {
    let with = |switches: &str| {
        EXAMPLE.replacen(
            "pdo = \"csp\"",
            &format!("pdo = \"csp-minimal\"\nswitches = {{ {switches} }}"),
            1,
        )
    };
    let c = Config::parse(
        &with(
            "negative_limit = { from = \"drive\", normally_closed = true }, reference = \"drive\"",
        ),
        "g.toml",
    )
    .unwrap();
    let x = &c.axes[0];
    let layout = x.pdo_layout().unwrap();
    let names: Vec<&str> = layout.inputs.iter().map(|o| o.name).collect();
    assert_eq!(
        names,
        [
            "Statusword",
            "Position actual value",
            "Digital inputs",
            "Touch probe status",
            "Touch probe position 1 positive value",
            "Touch probe position 1 negative value",
            "Touch probe position 2 positive value"
        ]
    );
    assert_eq!(
        layout.outputs.len(),
        3,
        "controlword, target, touch probe function"
    );
    let w = x.switches.wiring().unwrap();
    assert_eq!((w.used, w.inverted), (0b101, 0b001));
    // Without a reference switch, no probe unless asked for.
    let c = Config::parse(&with("positive_limit = \"drive\""), "g.toml").unwrap();
    assert_eq!(c.axes[0].pdo_layout().unwrap().inputs.len(), 3);
    let e = Config::parse(&with("reference = \"io\""), "g.toml")
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "g.toml:33: axis[0].switches.reference: \"io\": only \"drive\" (the drive's digital \
         inputs 0x60FD) is read; switches on an I/O module are not supported yet"
    );
}
