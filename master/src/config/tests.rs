use super::*;
use gantry_kernel::cam::Interpolation;
use gantry_kernel::AxisKind;

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
        "g.toml:33: axis[0].switches.reference: \"io\": \"drive\" (the drive's digital \
         inputs 0x60FD) or \"module\" (an input of an I/O module on the bus)"
    );
}

/// Switches on an I/O module: resolved with their polarity, not in the drive's 0x60FD
/// wiring; a module reference switch tells the kernel the probe cannot latch it; the
/// mistakes named; a CANopen node refused on EtherCAT.
#[test]
fn module_switches_are_resolved_and_refused_where_not_read() {
    let with = |switches: &str| {
        EXAMPLE.replacen(
            "pdo = \"csp\"",
            &format!("pdo = \"csp-minimal\"\nswitches = {{ {switches} }}"),
            1,
        )
    };
    let c = Config::parse(
        &with(
            "negative_limit = \"drive\", \
             positive_limit = { from = \"module\", slave = 3, input = 5, normally_closed = true }, \
             reference = { from = \"module\", slave = 3, input = 0 }",
        ),
        "g.toml",
    )
    .unwrap();
    let x = &c.axes[0];
    assert_eq!(
        x.switches.wiring().unwrap().used,
        0b001,
        "only the drive's bit 0"
    );
    let [neg, pos, reference] = x.switches.module_inputs().unwrap();
    assert_eq!(neg, None);
    assert_eq!(
        pos,
        Some(ModuleInput {
            slave: 3,
            input: 5,
            normally_closed: true
        })
    );
    assert_eq!(pos.unwrap().active(&[0b10_0000]), Some(false));
    assert_eq!(pos.unwrap().active(&[0]), Some(true));
    assert_eq!(pos.unwrap().active(&[]), None);
    assert_eq!(
        reference.map(|r| (r.input, r.normally_closed)),
        Some((0, false))
    );
    let k = x.kernel_config().unwrap();
    assert!(!k.reference_edges_latched && !k.limit_edges_latched);
    for (switches, why) in [
        (
            "reference = { from = \"module\", slave = 3 }",
            "axis[0].switches.reference: a module input needs its module and input",
        ),
        (
            "reference = { from = \"drive\", input = 2 }",
            "axis[0].switches.reference: slave and input are for from = \"module\"",
        ),
        (
            "positive_limit = { from = \"module\", slave = 1, input = 1 }, reference = \"drive\", \
             probe_source = { negative_limit = -1, positive_limit = -2 }",
            "axis[0].switches.probe_source: needs negative_limit and positive_limit from the \
             drive",
        ),
    ] {
        let e = Config::parse(&with(switches), "g.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(why), "{e}");
    }
    // `node` is CANopen's.
    let e = Config::parse(
        &with("reference = { from = \"module\", node = 9, input = 0 }"),
        "g.toml",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains(
            "axis[0].switches.reference: node = 9 is a CANopen node id; on EtherCAT a module \
             is named by its chain position (slave = N)"
        ),
        "{e}"
    );
}

/// A CANopen configuration with axes on nodes 1 and 2, `x_switches` and `y_switches` as
/// their `[axis.switches]` lines.
fn canopen_modules(x_switches: &str, y_switches: &str) -> String {
    format!(
        "[bus]\nkind = \"canopen\"\ninterface = \"can0\"\nbitrate = 1000000\n\
         cycle_us = 2000\n\
         [[axis]]\nname = \"x\"\nnode = 1\npdo = \"csp-minimal\"\n\
         scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n\
         max = {{ speed = 10.0, acceleration = 100.0, jerk = 1000.0 }}\n\
         [axis.switches]\n{x_switches}\n\
         [[axis]]\nname = \"y\"\nnode = 2\npdo = \"csp-minimal\"\n\
         scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n\
         max = {{ speed = 10.0, acceleration = 100.0, jerk = 1000.0 }}\n\
         [axis.switches]\n{y_switches}\n"
    )
}

/// Switches on CANopen I/O modules (`node = N`): each module placed on a bus position
/// after the drives, in the order first named, shared by the axes that read it, its
/// TPDO1 as wide as the highest input read; its TPDO counted in the bus load; the
/// mistakes named.
#[test]
fn canopen_module_switches_are_placed_after_the_drives_and_checked() {
    let c = Config::parse(
        &canopen_modules(
            "positive_limit = { from = \"module\", node = 9, input = 1, normally_closed = true }\n\
             reference = { from = \"module\", node = 10, input = 0 }",
            "negative_limit = { from = \"module\", node = 9, input = 12 }",
        ),
        "c.toml",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let modules = c.module_nodes();
    let got: Vec<_> = modules
        .iter()
        .map(|m| (m.node, m.position, m.groups, m.axes.join(",")))
        .collect();
    assert_eq!(
        got,
        [(9, 2, 2, "x,y".to_string()), (10, 3, 1, "x".to_string())]
    );
    let [neg, pos, reference] = c.axes[0].switches.module_inputs().unwrap();
    assert_eq!(neg, None);
    assert_eq!(
        pos,
        Some(ModuleInput {
            slave: 2,
            input: 1,
            normally_closed: true
        })
    );
    assert_eq!(reference.map(|r| r.slave), Some(3));
    assert_eq!(
        c.axes[1].switches.module_inputs().unwrap()[0].map(|m| (m.slave, m.input)),
        Some((2, 12))
    );
    // Not in the drive's 0x60FD; the module reference cannot be latched.
    assert_eq!(c.axes[0].switches.wiring().unwrap().used, 0);
    assert!(!c.kernel_axes[0].reference_edges_latched);
    // The bus load counts both modules' TPDOs and heartbeats: x's 4 PDOs (its drive's
    // touch probe stays mapped for the index pulse), y's 2, a 2-byte and a 1-byte TPDO.
    let load = crate::canopen::load::BusLoad::of_config(&c).unwrap();
    assert_eq!(load.pdos, [4, 2, 1, 1]);
    assert_eq!((load.drives, load.modules), (4, 2));
    assert!(
        load.to_string()
            .starts_with("2 drives + 2 I/O modules with 8 PDOs"),
        "{load}"
    );
    let no_modules = Config::parse(&canopen_modules("touch_probe = true", ""), "c.toml").unwrap();
    let plain = crate::canopen::load::BusLoad::of_config(&no_modules).unwrap();
    use gantry_drives::canopen::frame::frame_bits;
    // Two more heartbeats every 100 ms of 2 ms cycles: 6.5 bits a cycle instead of 3.9,
    // rounded up (7 against 4).
    assert_eq!(
        load.bits - plain.bits,
        frame_bits(2) + frame_bits(1) + 3,
        "{load}"
    );
    // The mistakes, by name.
    for (x, y, why) in [
        (
            "reference = { from = \"module\", slave = 2, input = 0 }",
            "",
            "axis[0].switches.reference: slave is an EtherCAT chain position; on \
             CANopen a module is named by its node id (node = N",
        ),
        (
            "reference = { from = \"module\", slave = 2, node = 9, input = 0 }",
            "",
            "axis[0].switches.reference: slave (an EtherCAT chain position) or node (a CANopen \
             node id), not both",
        ),
        (
            "reference = { from = \"module\", node = 9 }",
            "",
            "axis[0].switches.reference: a module input needs its module and input",
        ),
        (
            "reference = { from = \"module\", node = 0, input = 0 }",
            "",
            "axis[0].switches.reference: node 0 is outside 1..=127",
        ),
        (
            "reference = { from = \"module\", node = 127, input = 0 }",
            "",
            "axis[0].switches.reference: node 127 is gantry's own (bus.master_node)",
        ),
        (
            "reference = { from = \"module\", node = 9, input = 64 }",
            "",
            "axis[0].switches.reference: input 64: a CiA 401 module's TPDO1 carries inputs \
             0..=63",
        ),
        (
            "",
            "positive_limit = { from = \"module\", node = 1, input = 3 }",
            "axis[1].switches.positive_limit: node 1 is axis[0]'s drive (axis[1] reads it as \
             an I/O module)",
        ),
    ] {
        let e = Config::parse(&canopen_modules(x, y), "c.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(why), "{e}");
    }
}

/// `probe_source`: 0x60D0:1/:2 written at bring-up, 0x60BD mapped, MoveHome on a limit
/// switch allowed; its mistakes named; without it the kernel refuses that MoveHome.
#[test]
fn the_probe_source_for_the_limit_switches_is_checked_and_written() {
    let with = |switches: &str| {
        EXAMPLE.replacen(
            "pdo = \"csp\"",
            &format!("pdo = \"csp-minimal\"\nswitches = {{ {switches} }}"),
            1,
        )
    };
    let limits = "negative_limit = \"drive\", positive_limit = \"drive\", reference = \"drive\"";
    let c = Config::parse(
        &with(&format!(
            "{limits}, probe_source = {{ negative_limit = -1, positive_limit = -2 }}"
        )),
        "g.toml",
    )
    .unwrap();
    let x = &c.axes[0];
    assert_eq!(
        x.pdo_layout().unwrap().inputs.last().map(|o| o.index),
        Some(0x60BD)
    );
    let w: Vec<(u16, u8, Vec<u8>)> = x
        .switches
        .sdo_writes()
        .unwrap()
        .into_iter()
        .map(|w| (w.index, w.sub, w.value))
        .collect();
    assert_eq!(
        w,
        [
            (0x60D0, 1, (-1i16).to_le_bytes().to_vec()),
            (0x60D0, 2, (-2i16).to_le_bytes().to_vec())
        ]
    );
    assert!(x.kernel_config().unwrap().limit_edges_latched);
    // Without it: nothing written, no 0x60BD, the kernel told.
    let c = Config::parse(&with(limits), "g.toml").unwrap();
    assert!(c.axes[0].switches.sdo_writes().unwrap().is_empty());
    assert!(!c.axes[0].kernel_config().unwrap().limit_edges_latched);
    for (switches, why) in [
        (
            "positive_limit = \"drive\", reference = \"drive\", \
             probe_source = { negative_limit = -1, positive_limit = -2 }",
            "needs negative_limit and positive_limit from the drive",
        ),
        (
            &*format!("{limits}, probe_source = {{ negative_limit = 0, positive_limit = -2 }}"),
            "0 is reserved in 0x60D0 (ETG.6010); give the drive's values",
        ),
        (
            &*format!("{limits}, probe_source = {{ negative_limit = -3, positive_limit = -3 }}"),
            "negative_limit and positive_limit name the same source",
        ),
        (
            &*format!(
                "{limits}, touch_probe = false, \
                 probe_source = {{ negative_limit = -1, positive_limit = -2 }}"
            ),
            "needs the touch probe (a reference switch, or touch_probe = true)",
        ),
    ] {
        let e = Config::parse(&with(switches), "g.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with(&format!("axis[0].switches.probe_source: {why}")),
            "{e}"
        );
    }
}

#[test]
fn drive_homing_converts_to_counts_and_names_its_mistakes() {
    let with = |section: &str| {
        EXAMPLE.replacen(
            "pdo = \"csp\"",
            &format!("pdo = \"csp\"\ndrive_homing = {{ {section} }}"),
            1,
        )
    };
    let ok = "method = 19, speed_switch = 20.0, speed_zero = 2.0, acceleration = 200.0, \
              home_offset = -1.5, timeout = 12.0";
    let c = Config::parse(&with(ok), "g.toml").unwrap();
    // 131 072 counts per 5 mm.
    let p = c.axes[0].drive_homing_params().unwrap().unwrap();
    assert_eq!(
        (
            p.method,
            p.speed_switch,
            p.speed_zero,
            p.acceleration,
            p.home_offset
        ),
        (19, 524_288, 52_429, 5_242_880, -39_322)
    );
    assert_eq!((p.timeout_s, p.skip), (12.0, false));
    assert_eq!(
        c.axes[1].drive_homing_params().unwrap(),
        None,
        "not configured"
    );
    let e = |section: &str| {
        Config::parse(&with(section), "g.toml")
            .unwrap_err()
            .to_string()
    };
    assert_eq!(
        e("method = 19, speed_switch = 0.0, speed_zero = 2.0, acceleration = 200.0"),
        "g.toml:33: axis[0].drive_homing.speed_switch: 0 must be a finite number > 0"
    );
    assert_eq!(
        e("method = 19, speed_switch = 20.0, speed_zero = 900.0, acceleration = 200.0"),
        "g.toml:33: axis[0].drive_homing.speed_zero: 900 exceeds max.speed 250"
    );
    assert_eq!(
        e(
            "method = 19, speed_switch = 20.0, speed_zero = 2.0, acceleration = 200.0, \
           home_offset = 1e9"
        ),
        "g.toml:33: axis[0].drive_homing.home_offset: 1000000000 is beyond what the drive's \
         32 bits count"
    );
    let big = e("method = 300, speed_switch = 1.0, speed_zero = 1.0, acceleration = 1.0");
    assert!(big.starts_with("g.toml:33:"), "{big}");
    assert!(big.contains("300"), "{big}");
}

/// A CANopen configuration of `nodes` (one axis each, the minimal layout) with `bus`
/// lines added to `[bus]`.
fn canopen(nodes: &[&str], bus: &str) -> Result<Config, ConfigError> {
    let mut text =
        format!("[bus]\nkind = \"canopen\"\ninterface = \"can0\"\ncycle_us = 1000\n{bus}\n");
    for (i, node) in nodes.iter().enumerate() {
        text += &format!(
            "[[axis]]\nname = \"a{i}\"\n{node}\npdo = \"csp-minimal\"\n\
             scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n\
             max = {{ speed = 10.0, acceleration = 100.0, jerk = 1000.0 }}\n"
        );
    }
    Config::parse(&text, "c.toml")
}

#[test]
fn canopen_axes_are_on_bus_positions_in_file_order_by_node() {
    let c = canopen(&["node = 7", "node = 3"], "bitrate = 1000000").unwrap();
    assert_eq!(c.bus.bus_kind(), BusKind::Canopen);
    assert_eq!((c.axes[0].node, c.axes[0].drive), (Some(7), 0));
    assert_eq!((c.axes[1].node, c.axes[1].drive), (Some(3), 1));
    assert_eq!(c.bus.heartbeat_producer_ms(), DEFAULT_HEARTBEAT_MS);
    assert_eq!(c.bus.heartbeat_consumer_ms(), 300);
}

#[test]
fn canopen_mistakes_name_file_line_key_and_reason() {
    let e = |nodes: &[&str], bus: &str| canopen(nodes, bus).unwrap_err().to_string();
    assert_eq!(
        e(&["node = 1"], ""),
        "c.toml:1: bus.bitrate: missing: the CAN bit rate in bit/s (e.g. 1000000), which the \
         bus-load check weighs the cycle's frames against"
    );
    assert!(e(&["node = 1"], "bitrate = 900000")
        .contains("bus.bitrate: 900000 bit/s is not a CiA 102 bit rate"));
    assert_eq!(
        e(&["drive = 0"], "bitrate = 1000000"),
        "c.toml:8: axis[0].drive: on CANopen an axis names its drive by node id (node = N), \
         not by drive position"
    );
    assert_eq!(
        e(&["name2 = 1"], "bitrate = 1000000")
            .lines()
            .next()
            .unwrap(),
        "c.toml:8: name2: unknown field `name2`, expected one of `name`, `type`, `source`, `encoder_input`, `drive`, `node`, \
         `eds`, `kind`, `units`, `modulo`, `direction`, `software_limits`, `scaling`, `max`, \
         `defaults`, `quick_stop_deceleration`, `homing_required`, `target_monitoring`, `pdo`, `switches`, `drive_homing`, `commutation`, `encoder`, `homed_at_start`, \
         `sync_limit`"
    );
    assert!(e(&["", ""], "bitrate = 1000000")
        .ends_with("axis[0].node: missing: the CANopen node id of the axis' drive (1..=127)"));
    assert!(e(&["node = 0"], "bitrate = 1000000").ends_with(
        "axis[0].node: 0 is outside 1..=127 (CiA 301: a 7-bit node id, 0 addresses every node)"
    ));
    assert!(e(&["node = 4", "node = 4"], "bitrate = 1000000")
        .ends_with("axis[1].node: node 4 is also axis[0]'s"));
    assert!(e(
        &["node = 4"],
        "bitrate = 1000000\nheartbeat_timeout_ms = 100"
    )
    .contains("bus.heartbeat_timeout_ms: 100 ms is not longer than the heartbeat time 100 ms"));
    // Four minimal drives do not fit 1 Mbit/s at 1 ms: refused with the figure.
    let four = e(
        &["node = 1", "node = 2", "node = 3", "node = 4"],
        "bitrate = 1000000",
    );
    assert_eq!(
        four,
        "c.toml:5: bus.bitrate: 4 drives × 2 PDOs + SYNC at 1 kHz need 1.03 Mbit/s (979 bits \
         in the 950 µs the cycle waits for its TPDOs, heartbeats included); can0 has 1 Mbit/s"
    );
}

#[test]
fn canopen_settings_are_refused_on_ethercat_and_node_ids_too() {
    let l = line_of("cycle_us = 1000");
    let e = mistake("cycle_us = 1000", "cycle_us = 1000\nbitrate = 1000000");
    assert_eq!(
        e,
        format!(
            "g.toml:{}: bus.bitrate: is a CANopen setting (kind = \"canopen\"); EtherCAT runs \
             at 100 Mbit/s and its slaves have no heartbeat",
            l + 1
        )
    );
    let e = mistake("drive = 0", "drive = 0\nnode = 5");
    assert!(
        e.ends_with("axis[0].node: is a CANopen node id; on EtherCAT an axis names its drive's position (drive = N)"),
        "{e}"
    );
    let e = mistake("drive = 0", "# no drive");
    assert!(
        e.ends_with("axis[0].drive: missing: the position of the axis' drive in the chain (0 = next to the master)"),
        "{e}"
    );
    let e = mistake("kind = \"ethercat\"", "kind = \"profibus\"");
    assert!(
        e.ends_with(
            "bus.kind: \"profibus\" is not a bus gantry drives (\"ethercat\" or \"canopen\")"
        ),
        "{e}"
    );
}

#[test]
fn canopen_master_heartbeat_and_sync_counter_keys() {
    let c = canopen(&["node = 1"], "bitrate = 1000000").unwrap();
    assert_eq!(c.bus.master_node(), DEFAULT_MASTER_NODE);
    assert_eq!(c.bus.master_consumer_ms(), 300);
    assert_eq!(c.bus.sync_counter, None);
    let c = canopen(
        &["node = 1"],
        "bitrate = 1000000\nmaster_node = 100\nmaster_timeout_ms = 250\nsync_counter = 16",
    )
    .unwrap();
    assert_eq!(c.bus.master_node(), 100);
    assert_eq!(c.bus.master_consumer_ms(), 250);
    assert_eq!(c.bus.sync_counter, Some(16));
    let e = |nodes: &[&str], bus: &str| canopen(nodes, bus).unwrap_err().to_string();
    assert!(
        e(&["node = 127"], "bitrate = 1000000").ends_with(
            "axis[0].node: node 127 is gantry's own (bus.master_node, its heartbeat's): give \
             the drive another id or gantry another master_node"
        ),
        "{}",
        e(&["node = 127"], "bitrate = 1000000")
    );
    assert!(e(&["node = 1"], "bitrate = 1000000\nmaster_node = 0")
        .contains("bus.master_node: 0 is outside 1..=127"));
    assert!(
        e(&["node = 1"], "bitrate = 1000000\nmaster_timeout_ms = 100").contains(
            "bus.master_timeout_ms: 100 ms is not longer than gantry's heartbeat time 100 ms"
        )
    );
    // 101 ms: longer than the heartbeat, but not than the heartbeat and a 1 ms cycle.
    assert!(
        e(&["node = 1"], "bitrate = 1000000\nmaster_timeout_ms = 101").contains(
            "bus.master_timeout_ms: 101 ms is not longer than gantry's heartbeat time 100 ms \
             plus a cycle (1000 µs; the cycle sends it)"
        )
    );
    assert!(canopen(&["node = 1"], "bitrate = 1000000\nmaster_timeout_ms = 102").is_ok());
    for bad in [0, 1, 241] {
        assert!(
            e(
                &["node = 1"],
                &format!("bitrate = 1000000\nsync_counter = {bad}")
            )
            .contains(&format!(
                "bus.sync_counter: {bad} is not a synchronous counter overflow value"
            )),
            "{bad}"
        );
    }
    let ethercat = Config::parse(
        "[bus]\nkind = \"ethercat\"\ninterface = \"eth0\"\ncycle_us = 1000\nsync_counter = 4\n\
         [[axis]]\nname = \"a\"\ndrive = 0\n\
         scaling = { counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }\n\
         max = { speed = 10.0, acceleration = 100.0, jerk = 1000.0 }\n",
        "e.toml",
    )
    .unwrap_err()
    .to_string();
    assert!(
        ethercat.contains("bus.sync_counter: is a CANopen setting"),
        "{ethercat}"
    );
}

const ACME: &str = include_str!("../../../drives/tests/eds/acme_sx400.eds");

/// A directory of its own for a test's files.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("gantry-config-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `c.toml` in `dir`: one CANopen axis on node 5 with the full CSP layout and `eds`,
/// `bus` lines added; loaded.
fn with_eds(dir: &std::path::Path, eds: &str, bus: &str) -> Result<Config, ConfigError> {
    let text = format!(
        "[bus]\nkind = \"canopen\"\ninterface = \"can0\"\ncycle_us = 1000\n{bus}\n\
         [[axis]]\nname = \"x\"\nnode = 5\neds = \"{eds}\"\n\
         scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n\
         max = {{ speed = 10.0, acceleration = 100.0, jerk = 1000.0 }}\n"
    );
    let path = dir.join("c.toml");
    std::fs::write(&path, text).unwrap();
    Config::load(&path.display().to_string())
}

/// The vendor EDS with `old` replaced by `new` (in the section `section`), written to
/// `dir/acme.eds`; its path.
fn acme(dir: &std::path::Path, section: &str, old: &str, new: &str) -> String {
    let at = ACME.find(section).unwrap();
    let rel = ACME[at..]
        .find(old)
        .unwrap_or_else(|| panic!("{old} in {section}"));
    let text = format!(
        "{}{new}{}",
        &ACME[..at + rel],
        &ACME[at + rel + old.len()..]
    );
    let path = dir.join("acme.eds");
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

#[test]
fn an_axis_eds_is_read_relative_to_the_configuration_and_its_pdos_checked() {
    let dir = scratch("eds-ok");
    std::fs::write(dir.join("acme_sx400.eds"), ACME).unwrap();
    let c = with_eds(&dir, "acme_sx400.eds", "bitrate = 1000000").unwrap();
    let eds = c.eds_of(0).expect("the axis' EDS");
    assert_eq!(eds.device_info.vendor_name, "ACME Motion GmbH");
    assert_eq!(
        c.axes[0].eds.as_deref(),
        Some(dir.join("acme_sx400.eds").display().to_string().as_str())
    );
    // The bring-up writes only what the EDS has: ACME's drive has no 0x1006 (optional,
    // CiA 301 §7.5.2.6), so it is not told a cycle period; 0x1017 it is.
    let setup = crate::canopen::bring_up::drive_setup(&c, 0).unwrap();
    assert!(setup.steps.iter().all(|s| s.mux.index != 0x1006));
    assert!(setup.steps.iter().any(|s| s.mux.index == 0x1017));
    // Without an EDS the bring-up is as before: 0x1006 is written.
    let plain = canopen(&["node = 5"], "bitrate = 1000000").unwrap();
    assert!(plain.eds_of(0).is_none());
    let setup = crate::canopen::bring_up::drive_setup(&plain, 0).unwrap();
    assert!(setup.steps.iter().any(|s| s.mux.index == 0x1006));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_pdo_the_eds_does_not_allow_is_refused_at_load_naming_object_and_file() {
    let dir = scratch("eds-pdo");
    let eds = acme(&dir, "[6064]", "PDOMapping=1", "PDOMapping=0");
    let e = with_eds(&dir, "acme.eds", "bitrate = 1000000")
        .unwrap_err()
        .to_string();
    let c = dir.join("c.toml").display().to_string();
    assert_eq!(
        e,
        format!(
            "{c}:9: axis[0].eds: TPDO1 of pdo = \"csp\": 0x6064:00 is not PDO-mappable in {eds}"
        )
    );
    // A drive with one TPDO cannot take the CSP layout's two: named with the figures.
    let eds = acme(&dir, "[DeviceInfo]", "NrOfTXPDO=4", "NrOfTXPDO=1");
    let e = with_eds(&dir, "acme.eds", "bitrate = 1000000")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with(&format!(
            "axis[0].eds: CANopen node 5 (axis \"x\"): its process data need 2 TPDOs (15 \
             input bytes in PDOs of 8), the drive has 1 (NrOfTXPDO in {eds})"
        )),
        "{e}"
    );
    // A statusword mapped into an RPDO: its access (ro) says the other way.
    let eds = acme(&dir, "[6040]", "AccessType=rww", "AccessType=ro");
    let e = with_eds(&dir, "acme.eds", "bitrate = 1000000")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with(&format!(
            "axis[0].eds: RPDO1 of pdo = \"csp\": 0x6040:00 is ro in {eds}: not mappable into an RPDO"
        )),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_write_of_the_bring_up_the_eds_does_not_allow_is_refused_at_load() {
    let dir = scratch("eds-write");
    let eds = acme(&dir, "[1017]", "AccessType=rw", "AccessType=ro");
    let e = with_eds(&dir, "acme.eds", "bitrate = 1000000")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with(&format!(
            "axis[0].eds: the bring-up writes 0x0064 to 0x1017:00 (heartbeat producer time): \
             0x1017:00 is ro in {eds}: it cannot be configured"
        )),
        "{e}"
    );
    // The bit rate must be one the drive declares (BaudRate_800=0).
    std::fs::write(dir.join("acme.eds"), ACME).unwrap();
    let e = with_eds(&dir, "acme.eds", "bitrate = 800000")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with(&format!(
            "axis[0].eds: bus.bitrate 800 kbit/s is not one {} declares (BaudRate_800=1; it \
             has 10, 20, 50, 125, 250, 500, 1000)",
            dir.join("acme.eds").display()
        )),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_eds_that_cannot_be_read_is_named_with_its_line_and_section() {
    let dir = scratch("eds-bad");
    let eds = acme(&dir, "[6064]", "DataType=0x0004", "DataType=0x0099");
    let e = with_eds(&dir, "acme.eds", "bitrate = 1000000")
        .unwrap_err()
        .to_string();
    let line = ACME.lines().position(|l| l == "[6064]").unwrap() + 1;
    assert!(
        e.ends_with(&format!(
            "axis[0].eds: {eds}:{line}: [6064]: DataType 0x0099 is not a CiA 301 type"
        )),
        "{e}"
    );
    let e = with_eds(&dir, "missing.eds", "bitrate = 1000000")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!(
            "axis[0].eds: {}: cannot read:",
            dir.join("missing.eds").display()
        )),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_eds_is_refused_on_ethercat() {
    let e = mistake("drive = 0", "drive = 0\neds = \"drive.eds\"");
    assert!(
        e.ends_with(
            "axis[0].eds: is a CANopen device's EDS (CiA 306, kind = \"canopen\"); an \
             EtherCAT slave describes itself in its SII and gantry reads no ESI"
        ),
        "{e}"
    );
}

#[test]
fn gantrys_heartbeat_and_sync_counter_against_an_eds() {
    let dir = scratch("eds-master");
    std::fs::write(dir.join("acme_sx400.eds"), ACME).unwrap();
    // ACME's drive has 0x1016: it is given a consumer of gantry's heartbeat.
    let c = with_eds(&dir, "acme_sx400.eds", "bitrate = 1000000").unwrap();
    let setup = crate::canopen::bring_up::drive_setup(&c, 0).unwrap();
    let consumer = (127u32 << 16 | 300).to_le_bytes();
    assert!(setup
        .steps
        .iter()
        .any(|s| s.mux.index == 0x1016 && s.mux.sub == 1 && s.value() == consumer));
    // A drive without 0x1016 (optional, CiA 301 §7.5.2.16) is not told one.
    let text = ACME
        .replacen("[1016]", "[2F16]", 1)
        .replacen("8=0x1016", "8=0x2F16", 1);
    std::fs::write(dir.join("no1016.eds"), text).unwrap();
    let c = with_eds(&dir, "no1016.eds", "bitrate = 1000000").unwrap();
    let setup = crate::canopen::bring_up::drive_setup(&c, 0).unwrap();
    assert!(setup.steps.iter().all(|s| s.mux.index != 0x1016));
    // A SYNC counter needs 0x1019, which ACME's drive does not have: refused at load.
    let e = with_eds(
        &dir,
        "acme_sx400.eds",
        "bitrate = 1000000\nsync_counter = 8",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("0x1019:00"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn canopen_cycles_may_be_longer_than_ethercat_ones() {
    let ok = canopen(&["node = 1"], "bitrate = 125000\ncycle_us = 20000");
    // `canopen` writes cycle_us = 1000 first; TOML refuses a key twice, so build by hand.
    assert!(ok.is_err());
    let text =
        "[bus]\nkind = \"canopen\"\ninterface = \"can0\"\nbitrate = 125000\ncycle_us = 20000\n\
                [[axis]]\nname = \"a\"\nnode = 1\npdo = \"csp-minimal\"\n\
                scaling = { counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }\n\
                max = { speed = 10.0, acceleration = 100.0, jerk = 1000.0 }\n";
    assert_eq!(Config::parse(text, "c.toml").unwrap().bus.cycle_us, 20_000);
    let e = Config::parse(&text.replace("20000", "60000"), "c.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with("bus.cycle_us: 60000 µs is outside 250 to 50000 µs"),
        "{e}"
    );
    let e = mistake("cycle_us = 1000", "cycle_us = 20000");
    assert!(
        e.ends_with("bus.cycle_us: 20000 µs is outside 250 to 4000 µs"),
        "{e}"
    );
}

#[test]
fn homed_at_start_needs_an_absolute_encoder() {
    let x = "software_limits = [-10.0, 400.0]   # active once homed";
    let e = mistake(x, &format!("{x}\nhomed_at_start = true"));
    assert!(e.starts_with("g.toml:"), "{e}");
    assert!(
        e.ends_with(
            "axis[0].homed_at_start: needs an absolute encoder (encoder = \"absolute\"): an \
             incremental encoder's position is lost when the drive is switched off, so a saved \
             offset would home the axis at the wrong place"
        ),
        "{e}"
    );
    let e = mistake(x, &format!("{x}\nencoder = \"optical\""));
    assert!(e.contains("encoder") && e.contains("absolute"), "{e}");
    let ok = Config::parse(
        &EXAMPLE.replacen(
            x,
            &format!("{x}\nencoder = \"absolute\"\nhomed_at_start = true"),
            1,
        ),
        "g.toml",
    )
    .unwrap();
    assert_eq!(ok.axes[0].encoder, Encoder::Absolute);
    assert!(ok.axes[0].homed_at_start);
    assert_eq!(ok.axes[1].encoder, Encoder::Incremental);
}

#[test]
fn the_state_directory_is_relative_to_the_configuration() {
    let rt = "overrun_limit = 10            # overruns in a row before every axis stops";
    let e = mistake(rt, &format!("{rt}\n\n[service]\nstate_dir = \" \""));
    assert!(e.contains("service.state_dir: is empty"), "{e}");
    let dir = std::env::temp_dir().join(format!("gantry-config-state-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("g.toml");
    let with = |d: &str| EXAMPLE.replacen(rt, &format!("{rt}\n\n[service]\nstate_dir = {d:?}"), 1);
    std::fs::write(&path, with("state")).unwrap();
    let c = Config::load(&path.display().to_string()).unwrap();
    assert_eq!(
        c.service.state_dir,
        Some(dir.join("state").display().to_string())
    );
    std::fs::write(&path, with("/var/lib/g")).unwrap();
    let c = Config::load(&path.display().to_string()).unwrap();
    assert_eq!(c.service.state_dir.as_deref(), Some("/var/lib/g"));
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(
        Config::parse(EXAMPLE, "g.toml").unwrap().service.state_dir,
        None
    );
}

#[test]
fn commutation_objects_are_read_and_their_mistakes_named() {
    use gantry_drives::cia402::objects::DataType;
    use gantry_drives::commutation::{CommutationObjects, OffsetUnits, PolePairs};
    let with = |section: &str| {
        EXAMPLE.replacen(
            "pdo = \"csp\"",
            &format!("pdo = \"csp\"\ncommutation = {{ {section} }}"),
            1,
        )
    };
    let c = Config::parse(
        &with(
            "mode = -3, offset = { index = 0x3010, type = \"u16\" }, offset_units = 65536, \
             pole_pairs = 4, current = { index = 0x3012 }, angle = { index = 0x3013, sub = 2 }, \
             angle_units = 3600, current_per_mille = 250",
        ),
        "g.toml",
    )
    .unwrap();
    let o = c.axes[0].commutation.objects().unwrap();
    assert_eq!(o.mode, -3);
    assert_eq!(
        (o.offset.index, o.offset.sub, o.offset.kind),
        (0x3010, 0, DataType::U16)
    );
    assert_eq!(o.offset_units, OffsetUnits::PerElectricalRev(65536));
    assert_eq!(o.pole_pairs, PolePairs::Fixed(4));
    // The type left out: the default object's.
    assert_eq!((o.current.index, o.current.kind), (0x3012, DataType::U16));
    assert_eq!((o.angle.index, o.angle.sub), (0x3013, 2));
    assert_eq!(o.angle_units, 3600);
    assert_eq!(c.axes[0].commutation.current_per_mille, Some(250));
    // Left out: gantry-sim's.
    assert_eq!(
        c.axes[1].commutation.objects().unwrap(),
        CommutationObjects::default()
    );
    let c = Config::parse(
        &with("offset_units = \"counts\", pole_pairs = { index = 0x3011, type = \"u16\" }"),
        "g.toml",
    )
    .unwrap();
    let o = c.axes[0].commutation.objects().unwrap();
    assert_eq!(o.offset_units, OffsetUnits::Counts);
    assert!(
        matches!(o.pole_pairs, PolePairs::Object(p) if p.index == 0x3011 && p.kind == DataType::U16)
    );
    let e = |section: &str| {
        Config::parse(&with(section), "g.toml")
            .unwrap_err()
            .to_string()
    };
    let cases = [
        ("mode = 8", "commutation.mode: 8 is a CiA 402 mode"),
        (
            "angle_units = 100",
            "commutation.angle_units: 100 per electrical revolution is coarser than a degree",
        ),
        (
            "offset_units = 12",
            "commutation.offset_units: 12 per electrical revolution",
        ),
        (
            "pole_pairs = 0",
            "commutation.pole_pairs: 0 is not within 1 to 64",
        ),
        (
            "current = { index = 0x2103 }",
            "commutation.current: 0x2103:0 is angle's object too",
        ),
        (
            "angle = { index = 0x3013, type = \"u8\" }",
            "commutation.angle_units: 65536 does not fit the angle's object (U8)",
        ),
        (
            "offset = { index = 0x10 }",
            "commutation.offset: 0x0010 is not an object",
        ),
        (
            "current_per_mille = 0",
            "commutation.current_per_mille: 0 is not within 1 to 1000",
        ),
    ];
    for (section, want) in cases {
        let got = e(section);
        assert!(
            got.starts_with("g.toml:33: axis[0].") && got.contains(want),
            "{section}: {got}"
        );
    }
    // An unknown key is refused by name.
    assert!(e("offest = { index = 0x3010 }").contains("offest"));
}

/// `[bus] sdo_max_bytes`: the largest object `gantry sdo` moves, 64 KiB unless given,
/// 256 B to 16 MiB.
#[test]
fn sdo_max_bytes_defaults_to_64_kib_and_is_bounded() {
    let c = Config::parse(EXAMPLE, "g.toml").unwrap();
    assert_eq!(c.bus.sdo_max_bytes(), 65_536);
    let text = EXAMPLE.replacen(
        "cycle_us = 1000",
        "cycle_us = 1000\nsdo_max_bytes = 1048576",
        1,
    );
    let c = Config::parse(&text, "g.toml").unwrap();
    assert_eq!(c.bus.sdo_max_bytes(), 1 << 20);
    for bad in ["255", "16777217"] {
        let e = mistake(
            "cycle_us = 1000",
            &format!("cycle_us = 1000\nsdo_max_bytes = {bad}"),
        );
        assert!(
            e.contains(&format!(
                "bus.sdo_max_bytes: {bad} bytes is outside 256 to 16777216"
            )),
            "{e}"
        );
    }
}

/// An EtherCAT file with a real axis "x" on drive 0 and `extra` after it.
fn typed(extra: &str) -> String {
    format!(
        "[bus]\nkind = \"ethercat\"\ninterface = \"none\"\ncycle_us = 1000\n\
         [[axis]]\nname = \"x\"\ndrive = 0\n\
         scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n\
         max = {{ speed = 10.0, acceleration = 100.0, jerk = 1000.0 }}\n\
         {extra}"
    )
}

/// `typed(extra)`'s error text.
fn typed_error(extra: &str) -> String {
    Config::parse(&typed(extra), "k.toml")
        .unwrap_err()
        .to_string()
}

const MAX: &str = "max = { speed = 5.0, acceleration = 50.0, jerk = 500.0 }\n";
const EXTERNAL: &str = "[[axis]]\nname = \"e\"\ntype = \"external\"\nkind = \"rotary\"\n\
     modulo = 360.0\nscaling = { counts_per_motor_rev = 4096, units_per_load_rev = 360.0 }\n\
     [axis.encoder_input]\nslave = 2\n";

#[test]
fn every_axis_type_is_read_with_its_kernel_kind_and_bus_position() {
    let text = typed(&format!(
        "[[axis]]\nname = \"s\"\ntype = \"simulated\"\n{MAX}\
         [[axis]]\nname = \"v\"\ntype = \"virtual\"\n{MAX}\
         {EXTERNAL}\
         [[axis]]\nname = \"h\"\ntype = \"shadow\"\nsource = \"e\"\n"
    ));
    let c = Config::parse(&text, "k.toml").unwrap();
    let kinds: Vec<_> = c.kernel_axes.iter().map(|k| k.kind).collect();
    assert_eq!(
        kinds,
        [
            AxisKind::Real,
            AxisKind::Simulated,
            AxisKind::Virtual,
            AxisKind::External,
            AxisKind::Shadow { source: 3 }
        ]
    );
    let types: Vec<_> = c.axes.iter().map(|a| a.axis_type.name()).collect();
    assert_eq!(
        types,
        ["real", "simulated", "virtual", "external", "shadow"]
    );
    assert_eq!(c.drive_axes(), [0], "only the real axis has a drive");
    assert!(c.axes[1..].iter().all(|a| a.drive == DRIVE_UNSET));
    assert_eq!(c.axes[3].encoder_input.unwrap().slave, 2);
    assert_eq!(
        c.axes[3].encoder_input.unwrap().freeze_timeout_ms,
        DEFAULT_FREEZE_TIMEOUT_MS
    );
    // Without scaling a simulated or virtual axis counts one count per unit; a virtual
    // axis needs no homing; the shadow takes its source's mechanics and units.
    assert_eq!(c.axes[2].scaling, UNIT_SCALING);
    assert!(!c.kernel_axes[2].homing_required);
    assert_eq!(c.kernel_axes[4].mechanics, c.kernel_axes[3].mechanics);
    assert_eq!(c.axes[4].modulo, Some(360.0));
    assert_eq!(c.kernel_axes[4].name, "h");
    // An external axis without `max` has the kernel's limits (it is never commanded).
    assert_eq!(
        c.kernel_axes[3].max,
        AxisConfig::new("e", AxisKind::External).max
    );
}

#[test]
fn each_type_rule_is_refused_naming_file_axis_key_and_reason() {
    let cases: &[(String, &str)] = &[
        (
            format!("[[axis]]\nname = \"s\"\ntype = \"simulated\"\ndrive = 1\n{MAX}"),
            "axis[1].drive: a simulated axis has no drive; remove drive",
        ),
        (
            format!("[[axis]]\nname = \"v\"\ntype = \"virtual\"\ndrive = 1\n{MAX}"),
            "axis[1].drive: a virtual axis has no drive; remove drive",
        ),
        (
            format!("[[axis]]\nname = \"v\"\ntype = \"virtual\"\nnode = 3\n{MAX}"),
            "axis[1].node: a virtual axis has no drive; remove node",
        ),
        (
            "[[axis]]\nname = \"v\"\ntype = \"virtual\"\n".into(),
            "axis[1].max: missing: what a virtual axis may be commanded (max = { \
             speed = V, acceleration = A, jerk = J })",
        ),
        (
            format!("[[axis]]\nname = \"s\"\ntype = \"simulated\"\nsource = \"x\"\n{MAX}"),
            "axis[1].source: a simulated axis mirrors nothing (only a shadow axis \
             has a source)",
        ),
        (
            format!(
                "[[axis]]\nname = \"v\"\ntype = \"virtual\"\n{MAX}[axis.encoder_input]\nslave = 1\n"
            ),
            "axis[1].encoder_input: a virtual axis reads no encoder module (only an \
             external axis has [axis.encoder_input])",
        ),
        (
            "[[axis]]\nname = \"e\"\ntype = \"external\"\n\
             scaling = { counts_per_motor_rev = 4096, units_per_load_rev = 1.0 }\n"
                .into(),
            "axis[1].encoder_input: missing: the encoder module an external axis \
             reads ([axis.encoder_input] slave = N, its EtherCAT position)",
        ),
        (
            "[[axis]]\nname = \"e\"\ntype = \"external\"\n[axis.encoder_input]\nslave = 1\n"
                .into(),
            "axis[1].scaling: missing: a external axis counts encoder counts \
             (scaling = { counts_per_motor_rev = N, units_per_load_rev = X })",
        ),
        (
            EXTERNAL.replace("slave = 2\n", "slave = 2\nfreeze_timeout_ms = 0\n"),
            "axis[1].encoder_input.freeze_timeout_ms: 0 is not a time > 0 (ms without \
             a new value from the module before the axis is lost)",
        ),
        (
            EXTERNAL.replace("slave = 2\n", "slave = 2\nfreeze_timeout_ms = -3.0\n"),
            "axis[1].encoder_input.freeze_timeout_ms: -3 is not a time > 0 (ms \
             without a new value from the module before the axis is lost)",
        ),
        (
            EXTERNAL.replace("slave = 2\n", "slave = 2\nfreeze_timeout_ms = 0.5\n"),
            "axis[1].encoder_input.freeze_timeout_ms: 0.5 ms is shorter than the bus \
             cycle (1000 µs): the module cannot toggle faster than the master reads it",
        ),
        (
            EXTERNAL.replace("slave = 2", "slave = 0"),
            "axis[1].encoder_input.slave: slave 0 is also axis[0]'s",
        ),
        (
            format!("{EXTERNAL}[[axis]]\nname = \"y\"\ndrive = 2\n{MAX}scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n"),
            "axis[2].drive: drive 2 is also axis[1]'s",
        ),
        (
            "[[axis]]\nname = \"h\"\ntype = \"shadow\"\n".into(),
            "axis[1].source: missing: the name of the axis a shadow axis mirrors",
        ),
        (
            "[[axis]]\nname = \"h\"\ntype = \"shadow\"\nsource = \"nope\"\n".into(),
            "axis[1].source: \"nope\" is not a non-shadow axis of this file (a shadow \
             mirrors a real, simulated, virtual or external axis)",
        ),
        (
            "[[axis]]\nname = \"h\"\ntype = \"shadow\"\nsource = \"x\"\n\
             [[axis]]\nname = \"h2\"\ntype = \"shadow\"\nsource = \"h\"\n"
                .into(),
            "axis[2].source: \"h\" is not a non-shadow axis of this file (a shadow \
             mirrors a real, simulated, virtual or external axis)",
        ),
        (
            format!("[[axis]]\nname = \"h\"\ntype = \"shadow\"\nsource = \"x\"\n{MAX}"),
            "axis[1].max: a shadow axis takes its max from its source; remove max",
        ),
        (
            "[[axis]]\nname = \"h\"\ntype = \"shadow\"\nsource = \"x\"\nmodulo = 360.0\n".into(),
            "axis[1].modulo: a shadow axis takes its modulo from its source; remove \
             modulo",
        ),
        (
            format!("[[axis]]\nname = \"v\"\ntype = \"virtual\"\n{MAX}[axis.drive_homing]\nmethod = 35\nspeed_switch = 1.0\nspeed_zero = 0.5\nacceleration = 10.0\n"),
            "axis[1].drive_homing: a virtual axis has no drive to home; remove \
             [axis.drive_homing]",
        ),
        (
            format!("[[axis]]\nname = \"v\"\ntype = \"virtual\"\n{MAX}[axis.switches]\ntouch_probe = true\n"),
            "axis[1].switches: a virtual axis reads no switches (they are read from a \
             drive or an I/O module for a real axis); remove [axis.switches]",
        ),
    ];
    for (extra, want) in cases {
        let got = typed_error(extra);
        let (at, rest) = got.split_once(": ").unwrap();
        assert!(at.starts_with("k.toml:"), "{got}");
        assert_eq!(rest, *want, "{extra}");
    }
    // The line is the key's.
    let e = typed_error(&format!(
        "[[axis]]\nname = \"s\"\ntype = \"simulated\"\ndrive = 1\n{MAX}"
    ));
    assert!(e.starts_with("k.toml:13: axis[1].drive: "), "{e}");
    // A type that does not exist: serde names the ones that do.
    let e = typed_error("[[axis]]\nname = \"q\"\ntype = \"servo\"\n");
    assert!(
        e.starts_with(
            "k.toml:12: type: unknown variant `servo`, expected one of `real`, \
             `simulated`, `virtual`, `external`, `shadow`"
        ),
        "{e}"
    );
}

#[test]
fn on_canopen_only_real_axes_are_nodes_and_external_axes_are_refused() {
    let axis = |name: &str, node: u8| {
        format!(
            "[[axis]]\nname = \"{name}\"\nnode = {node}\n\
             scaling = {{ counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }}\n{MAX}"
        )
    };
    let head =
        "[bus]\nkind = \"canopen\"\ninterface = \"vcan0\"\ncycle_us = 2000\nbitrate = 1000000\n";
    let text = format!(
        "{head}[[axis]]\nname = \"v\"\ntype = \"virtual\"\n{MAX}{}\
         [[axis]]\nname = \"s\"\ntype = \"simulated\"\n{MAX}{}",
        axis("a", 5),
        axis("b", 6)
    );
    let c = Config::parse(&text, "c.toml").unwrap();
    let drives: Vec<_> = c.axes.iter().map(|a| a.drive).collect();
    assert_eq!(drives, [DRIVE_UNSET, 0, DRIVE_UNSET, 1]);
    assert_eq!(c.drive_axes(), [1, 3]);
    assert_eq!(
        c.axis_on_drive(1).map(|(i, a)| (i, a.name.as_str())),
        Some((3, "b"))
    );
    let setups = crate::canopen::bring_up::drive_setups(&c).unwrap();
    let nodes: Vec<_> = setups.iter().map(|s| s.node.get()).collect();
    assert_eq!(nodes, [5, 6]);
    let e = Config::parse(&format!("{head}{}", EXTERNAL), "c.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("axis[0].type: an external axis reads an EtherCAT encoder module"),
        "{e}"
    );
}

/// The example with `cams` (`[[cam]]` sections) appended, written to a fresh directory
/// beside the shipped cam files (`cams/`); the loaded configuration or its error text.
fn with_cams(tag: &str, cams: &str) -> (Result<Config, String>, std::path::PathBuf, String) {
    let dir = std::env::temp_dir().join(format!("gantry-config-cam-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("cams")).unwrap();
    for f in ["flying_knife.csv", "eccentric.toml"] {
        let from = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/cams/");
        std::fs::copy(format!("{from}{f}"), dir.join("cams").join(f)).unwrap();
    }
    let text = format!("{EXAMPLE}\n{cams}");
    let path = dir.join("g.toml");
    std::fs::write(&path, &text).unwrap();
    let loaded = Config::load(&path.display().to_string()).map_err(|e| e.to_string());
    (loaded, dir, text)
}

fn line_in(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn cam_tables_are_loaded_relative_to_the_configuration_in_slot_order() {
    let (c, dir, _) = with_cams(
        "ok",
        "[[cam]]\nname = \"knife\"\nfile = \"cams/flying_knife.csv\"\ninterpolation = \"quintic\"\n\n\
         [[cam]]\nname = \"press\"\nfile = \"cams/eccentric.toml\"\nperiodic = true\n",
    );
    let c = c.unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(c.cams.len(), 2);
    let knife = &c.cams[0];
    assert_eq!((knife.name.as_str(), knife.slot), ("knife", 0));
    assert_eq!(
        knife.file,
        dir.join("cams/flying_knife.csv").display().to_string()
    );
    assert_eq!(knife.table.points().len(), 25);
    assert_eq!(knife.table.interpolation(), Interpolation::Quintic);
    assert!(!knife.table.is_periodic());
    assert_eq!(knife.table.master_range(), (0.0, 600.0));
    let press = &c.cams[1];
    assert_eq!((press.name.as_str(), press.slot), ("press", 1));
    assert!(press.table.is_periodic());
    assert_eq!(press.table.interpolation(), Interpolation::Cubic);
    assert!(
        Config::parse(EXAMPLE, "g.toml").unwrap().cams.is_empty(),
        "no [[cam]]: no tables"
    );
}

#[test]
fn cam_section_mistakes_name_file_line_section_key_and_reason() {
    let cases: [(&str, &str, &str, &str); 7] = [
        (
            "empty",
            "[[cam]]\nname = \" \"\nfile = \"cams/flying_knife.csv\"\n",
            "name = \" \"",
            "cam[0].name: is empty: name the table",
        ),
        (
            "twice",
            "[[cam]]\nname = \"k\"\nfile = \"cams/flying_knife.csv\"\n\n[[cam]]\nname  = \"k\"\nfile = \"cams/eccentric.toml\"\n",
            "name  = \"k\"",
            "cam[1].name: \"k\" is also cam[0]",
        ),
        (
            "interp",
            "[[cam]]\nname = \"k\"\nfile = \"cams/flying_knife.csv\"\ninterpolation = \"spline\"\n",
            "interpolation = \"spline\"",
            "cam[0].interpolation: \"spline\" is none of linear, cubic, quintic",
        ),
        (
            "missing",
            "[[cam]]\nname = \"k\"\nfile = \"cams/nowhere.csv\"\n",
            "file = \"cams/nowhere.csv\"",
            "cam[0].file: cannot read cam file ",
        ),
        (
            "ext",
            "[[cam]]\nname = \"k\"\nfile = \"cams/flying_knife.txt\"\n",
            "file = \"cams/flying_knife.txt\"",
            "cam[0].file: cam file ",
        ),
        (
            "conflict",
            "[[cam]]\nname = \"press\"\nfile = \"cams/eccentric.toml\"\nperiodic = false\n",
            "file = \"cams/eccentric.toml\"",
            "cam[0].file: ",
        ),
        (
            "unknown",
            "[[cam]]\nname = \"k\"\nfile = \"cams/flying_knife.csv\"\nperiodical = true\n",
            "periodical = true",
            "periodical: unknown field `periodical`",
        ),
    ];
    for (tag, cams, at, says) in cases {
        let (c, dir, text) = with_cams(tag, cams);
        std::fs::remove_dir_all(&dir).unwrap();
        let e = c.unwrap_err();
        let line = line_in(&text, at);
        let want = format!("{}:{line}: {says}", dir.join("g.toml").display());
        assert!(e.starts_with(&want), "{tag}: {e}\n wanted {want}");
    }
    // The conflict says what disagrees with what.
    let (c, dir, _) = with_cams(
        "conflict-text",
        "[[cam]]\nname = \"press\"\nfile = \"cams/eccentric.toml\"\nperiodic = false\n",
    );
    std::fs::remove_dir_all(&dir).unwrap();
    let e = c.unwrap_err();
    assert!(
        e.contains("eccentric.toml") && e.contains("periodic"),
        "{e}"
    );
    // A table the kernel refuses (master not increasing) names the file and the point.
    let dir = std::env::temp_dir().join(format!("gantry-config-cam-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("bad.csv"), "0,0\n10,1\n5,2\n").unwrap();
    let text = format!("{EXAMPLE}\n[[cam]]\nname = \"bad\"\nfile = \"bad.csv\"\n");
    std::fs::write(dir.join("g.toml"), &text).unwrap();
    let e = Config::load(&dir.join("g.toml").display().to_string())
        .unwrap_err()
        .to_string();
    std::fs::remove_dir_all(&dir).unwrap();
    let line = line_in(&text, "file = \"bad.csv\"");
    assert!(e.contains(&format!("g.toml:{line}: cam[0].file: ")), "{e}");
    assert!(e.contains("bad.csv"), "{e}");
}

#[test]
fn at_most_cam_slots_tables() {
    use gantry_kernel::kernel::CAM_SLOTS;
    let section =
        |i: usize| format!("[[cam]]\nname = \"t{i}\"\nfile = \"cams/flying_knife.csv\"\n\n");
    let full: String = (0..CAM_SLOTS).map(section).collect();
    let (c, dir, _) = with_cams("full", &full);
    std::fs::remove_dir_all(&dir).unwrap();
    let c = c.unwrap();
    assert_eq!(c.cams.len(), CAM_SLOTS);
    assert_eq!(c.cams[CAM_SLOTS - 1].slot, CAM_SLOTS - 1);
    let over = format!("{full}{}", section(CAM_SLOTS));
    let (c, dir, text) = with_cams("over", &over);
    std::fs::remove_dir_all(&dir).unwrap();
    let e = c.unwrap_err();
    let line = line_in(&text, &format!("name = \"t{CAM_SLOTS}\""));
    assert!(
        e.ends_with(&format!(
            ":{line}: cam[{CAM_SLOTS}].name: {CAM_SLOTS} cam tables at most (the kernel's cam slots)"
        )),
        "{e}"
    );
}

#[test]
fn sync_limit_is_errorstop_by_default_warning_when_told_and_a_wrong_word_is_named() {
    use gantry_kernel::axis::SyncLimitReaction;
    let text = typed(&format!(
        "[[axis]]\nname = \"s\"\ntype = \"simulated\"\nsync_limit = \"warning\"\n{MAX}"
    ));
    let c = Config::parse(&text, "k.toml").unwrap();
    assert_eq!(
        c.kernel_axes[0].sync_limit_reaction,
        SyncLimitReaction::ErrorStop
    );
    assert_eq!(
        c.kernel_axes[1].sync_limit_reaction,
        SyncLimitReaction::Warning
    );
    let bad = typed(&format!(
        "[[axis]]\nname = \"s\"\ntype = \"simulated\"\nsync_limit = \"ignore\"\n{MAX}"
    ));
    let e = Config::parse(&bad, "k.toml").unwrap_err().to_string();
    assert!(
        e.contains("sync_limit") && e.contains("ignore") && e.contains("warning"),
        "{e}"
    );
}

#[test]
fn groups_name_their_axes_and_each_mistake_is_named() {
    let virt = format!("[[axis]]\nname = \"v\"\ntype = \"virtual\"\n{MAX}");
    let text = typed(&format!(
        "{virt}[[group]]\nname = \"xv\"\naxes = [\"x\", \"v\"]\n"
    ));
    let c = Config::parse(&text, "k.toml").unwrap();
    assert_eq!(c.groups.len(), 1);
    assert_eq!(c.groups[0].name, "xv");
    assert_eq!(c.groups[0].axes, [0, 1]);
    let e = typed_error(&format!(
        "{virt}[[group]]\nname = \"g\"\naxes = [\"x\", \"w\"]\n"
    ));
    assert!(
        e.contains("group[0].axes") && e.contains("\"w\" is no [[axis]]"),
        "{e}"
    );
    let e = typed_error(&format!(
        "{virt}[[group]]\nname = \"g\"\naxes = [\"x\"]\n[[group]]\nname = \"g\"\naxes = [\"v\"]\n"
    ));
    assert!(
        e.contains("group[1].name") && e.contains("also group[0]"),
        "{e}"
    );
    let e = typed_error(&format!(
        "{EXTERNAL}[[group]]\nname = \"g\"\naxes = [\"x\", \"e\"]\n"
    ));
    assert!(e.contains("group[0].axes") && e.contains("external"), "{e}");
    let e = typed_error(&format!(
        "{virt}[[group]]\nname = \"g\"\naxes = [\"x\", \"x\"]\n"
    ));
    assert!(e.contains("group[0].axes"), "{e}");
    let e = typed_error("[[group]]\nname = \"\"\naxes = [\"x\"]\n");
    assert!(e.contains("group[0].name") && e.contains("empty"), "{e}");
}

#[test]
fn a_groups_corner_deviation_is_its_moves_default_and_a_bad_one_names_the_group() {
    let virt = format!("[[axis]]\nname = \"v\"\ntype = \"virtual\"\n{MAX}");
    let text = typed(&format!(
        "{virt}[[group]]\nname = \"xv\"\naxes = [\"x\", \"v\"]\ncorner_deviation = 0.5\n\
         [[group]]\nname = \"v\"\naxes = [\"v\"]\n"
    ));
    let c = Config::parse(&text, "k.toml").unwrap();
    let deviations: Vec<f64> = c
        .group_defaults
        .iter()
        .map(|d| d.corner_deviation)
        .collect();
    // Left out: the axes' limits alone decide.
    assert_eq!(deviations, [0.5, f64::INFINITY]);
    for bad in ["0", "-0.5", "nan", "inf"] {
        let e = typed_error(&format!(
            "{virt}[[group]]\nname = \"xv\"\naxes = [\"x\", \"v\"]\ncorner_deviation = {bad}\n"
        ));
        assert!(
            e.contains("group[0].corner_deviation: group \"xv\": ")
                && e.contains("is not a corner deviation (a finite number of units > 0)"),
            "{bad}: {e}"
        );
    }
}
