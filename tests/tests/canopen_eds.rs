//! The master with a vendor's EDS (CiA 306-1), lockstep on the in-memory CAN bus at
//! 1 Mbit/s: the simulator writes its servo's EDS (as a vendor would ship it), a
//! configuration names it (`[[axis]] eds = "servo.eds"`, relative to the file), the
//! configuration is checked against it at load and the bus comes up on the simulated
//! nodes and moves (a node whose identity is not the EDS' device stops the bring-up); an EDS that says an object of the layout is not mappable refuses the
//! configuration before anything is sent, naming the object and the file; the DCF of
//! what the bring-up configured reads back with the shared reader and holds, object by
//! object, what the simulated nodes' dictionaries hold after the bring-up.

use std::path::{Path, PathBuf};

use gantry::config::Config;
use gantry_cli::sdo::{self, Target, Typing};
use gantry_drives::canopen::eds::DataType;
use gantry_drives::canopen::eds::{self, PdoDirection};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::can_rig::{servos, CanRig};

fn dir(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gantry-canopen-eds-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The EDS the simulator writes for its servo (what `gantry-sim eds` writes), in `dir`.
fn simulated_servo_eds(dir: &Path) -> String {
    let mut node = servos(&[1]).remove(0);
    let text = gantry_sim::canopen::eds::write(&mut node, "servo.eds");
    std::fs::write(dir.join("servo.eds"), &text).unwrap();
    text
}

/// `c.toml` in `dir`: an axis with `eds` on each of `nodes`, the full CSP layout, 2 ms
/// at 1 Mbit/s; loaded.
fn config(dir: &Path, nodes: &[u8], eds: &str) -> Result<Config, gantry::config::ConfigError> {
    let mut text = "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\n\
                    cycle_us = 2000\n"
        .to_string();
    for (i, node) in nodes.iter().enumerate() {
        text += &format!(
            "[[axis]]\nname = \"a{i}\"\nnode = {node}\neds = \"{eds}\"\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }}\n"
        );
    }
    let path = dir.join("c.toml");
    std::fs::write(&path, text).unwrap();
    Config::load(&path.display().to_string())
}

/// `index:sub` of `node` as its SDO server reads it.
fn read(rig: &CanRig, node: u8, index: u16, sub: u8) -> Vec<u8> {
    let mut sim = rig.sim();
    let mut out = [0u8; 64];
    let n = sim
        .node_mut(node)
        .read_object(index, sub, &mut out)
        .unwrap_or_else(|e| panic!("node {node} 0x{index:04X}:{sub}: {e}"));
    out[..n].to_vec()
}

#[test]
fn the_bus_comes_up_and_moves_with_the_eds_the_simulator_wrote() {
    let d = dir("up");
    simulated_servo_eds(&d);
    let ids = [3, 7];
    let config = config(&d, &ids, "servo.eds").unwrap_or_else(|e| panic!("{e}"));
    assert!(config.eds_of(1).is_some());
    let mut rig = CanRig::new(&config, servos(&ids));
    assert!(
        rig.log
            .contains("node 7: RPDO1 7 bytes, TPDO1 8 bytes, TPDO2 7 bytes"),
        "{}",
        rig.log
    );
    for axis in 0..ids.len() {
        rig.enable_and_home(axis);
    }
    let h = rig.start_move(1, 10.0);
    assert_eq!(rig.finish(&h, 5000), CommandStatus::Done);
    let at = rig.snapshot().axes[1].actual_position;
    assert!((at - 10.0).abs() < 0.01, "axis 1 at {at}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_layout_the_eds_does_not_allow_is_refused_before_anything_is_sent() {
    let d = dir("refused");
    let text = simulated_servo_eds(&d);
    // The same device, but its EDS says the position actual value cannot be mapped.
    let at = text.find("[6064]").expect("0x6064 in the simulated EDS");
    let end = text[at..].find("\n[").map_or(text.len(), |e| at + e);
    let section = &text[at..end];
    assert!(section.contains("PDOMapping=1"), "{section}");
    let changed = format!(
        "{}{}{}",
        &text[..at],
        section.replace("PDOMapping=1", "PDOMapping=0"),
        &text[end..]
    );
    std::fs::write(d.join("strict.eds"), changed).unwrap();
    let e = config(&d, &[3], "strict.eds").unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "{}:9: axis[0].eds: TPDO1 of pdo = \"csp\": 0x6064:00 is not PDO-mappable in {}",
            d.join("c.toml").display(),
            d.join("strict.eds").display()
        )
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn the_dcf_reads_back_and_holds_what_the_bring_up_wrote_on_each_node() {
    let d = dir("dcf");
    simulated_servo_eds(&d);
    let ids = [3, 7];
    let config = config(&d, &ids, "servo.eds").unwrap_or_else(|e| panic!("{e}"));
    let rig = CanRig::new(&config, servos(&ids));
    for (axis, &node) in ids.iter().enumerate() {
        let sheet = config.eds_of(axis).unwrap();
        let dcf = gantry::canopen::eds::dcf(&config, axis, sheet).unwrap();
        let text = eds::write_dcf(&dcf);
        let back = eds::read(&text, "node.dcf").unwrap_or_else(|e| panic!("{e}"));
        let c = back.commissioning.as_ref().expect("[DeviceComissioning]");
        assert_eq!((c.node_id, c.baudrate_kbit), (node, 1000));
        assert_eq!(c.node_name, format!("a{axis}"));
        let setup = gantry::canopen::bring_up::drive_setup(&config, axis).unwrap();
        let mut written: Vec<(u16, u8)> = setup
            .steps
            .iter()
            .map(|s| (s.mux.index, s.mux.sub))
            .collect();
        written.sort_unstable();
        written.dedup();
        let mut configured = Vec::new();
        for (index, object) in &back.objects {
            for (sub, entry) in &object.subs {
                let Some(value) = &entry.parameter_value else {
                    continue;
                };
                configured.push((*index, *sub));
                let bytes = value.to_le_bytes(entry.data_type, node).unwrap();
                assert_eq!(
                    bytes,
                    read(&rig, node, *index, *sub),
                    "node {node} 0x{index:04X}:{sub:02X}: the DCF says {value:?}"
                );
            }
        }
        // Every object the bring-up wrote has its value, and nothing else.
        assert_eq!(configured, written, "node {node}");
        // Figures a reader of the DCF would look for.
        let value = |index: u16, sub: u8| {
            back.entry(index, sub)
                .and_then(|e| e.parameter_value.as_ref())
                .and_then(|v| v.integer_on(node))
        };
        assert_eq!(
            value(0x1A00, 1),
            Some(0x6064_0020),
            "TPDO1 maps the position"
        );
        assert_eq!(value(0x1A00, 0), Some(2));
        assert_eq!(value(0x1800, 1), Some(0x180 + i128::from(node)));
        assert_eq!(
            value(0x1403, 1),
            Some((1 << 31) | (0x500 + i128::from(node)))
        );
        assert_eq!(value(0x1017, 0), Some(100));
        assert_eq!(value(0x1006, 0), Some(2000));
        assert!(back.pdo_mappable(0x6064, 0, PdoDirection::Transmit));
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn gantry_dcf_takes_the_simulated_nodes_eds_for_an_axis_without_one() {
    let d = dir("cli");
    std::fs::write(
        d.join("chain.toml"),
        "[[slave]]\nkind = \"servo\"\nnode = 4\n",
    )
    .unwrap();
    let text = "[bus]\nkind = \"canopen\"\nsimulator = \"chain.toml\"\nbitrate = 500000\n\
                cycle_us = 2000\n[[axis]]\nname = \"x\"\nnode = 4\npdo = \"csp-minimal\"\n\
                scaling = { counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }\n\
                max = { speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }\n";
    let path = d.join("g.toml");
    std::fs::write(&path, text).unwrap();
    let out = d.join("x.dcf");
    let said = gantry_cli::dcf::run(&path.display().to_string(), "x", &out).unwrap();
    assert_eq!(
        said,
        format!("gantry: DCF of axis \"x\" written to {}", out.display())
    );
    let back = eds::load(&out).unwrap_or_else(|e| panic!("{e}"));
    let c = back.commissioning.as_ref().unwrap();
    assert_eq!((c.node_id, c.baudrate_kbit), (4, 500));
    assert_eq!(back.file_info.file_name, "x.dcf");
    // The minimal layout: statusword and position in TPDO1.
    let tpdo1 = |sub: u8| {
        back.entry(0x1A00, sub)
            .and_then(|e| e.parameter_value.as_ref())
            .and_then(|v| v.integer_on(4))
    };
    assert_eq!(tpdo1(0), Some(2));
    assert_eq!(tpdo1(1), Some(0x6064_0020));
    assert_eq!(tpdo1(2), Some(0x6041_0010));
    // An axis the file does not have, and one without an EDS on a real bus.
    let e = gantry_cli::dcf::run(&path.display().to_string(), "y", &out)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        format!("{} has no axis \"y\" (its axes: x)", path.display())
    );
    std::fs::write(
        &path,
        text.replace("simulator = \"chain.toml\"", "interface = \"can0\""),
    )
    .unwrap();
    let e = gantry_cli::dcf::run(&path.display().to_string(), "x", &out)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("axis \"x\" names no EDS"), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn gantry_sdo_types_objects_by_the_eds_and_refuses_what_it_does_not_have() {
    let d = dir("sdo");
    simulated_servo_eds(&d);
    let config = config(&d, &[3], "servo.eds").unwrap_or_else(|e| panic!("{e}"));
    let rig = CanRig::new(&config, servos(&[3]));
    // The control socket of a service on this bus (the cycle is not needed: what is
    // checked here is answered from the configuration, before the bus is asked).
    let state = gantry::service::server::ServerState::new(rig.ctl.clone(), config.clone(), false);
    let socket = d.join("gantry.sock");
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    let listener = rt
        .block_on(async { gantry::service::server::bind(&socket) })
        .unwrap();
    rt.spawn(gantry::service::server::serve(listener, state));
    let mut client = gantry_cli::client::Client::connect(&socket).unwrap();
    let eds = d.join("servo.eds").display().to_string();
    let axis = || Some("a0".to_string());
    // Without --type: the EDS' type, by axis or by bus position.
    assert_eq!(
        sdo::typing(&mut client, axis(), None, 0x6064, 0, None).unwrap(),
        Typing::Eds {
            ty: DataType::Integer32,
            node: 3
        }
    );
    assert_eq!(
        sdo::typing(&mut client, None, Some(0), 0x6041, 0, None).unwrap(),
        Typing::Eds {
            ty: DataType::Unsigned16,
            node: 3
        }
    );
    // A given --type is taken as it is.
    assert_eq!(
        sdo::typing(
            &mut client,
            axis(),
            None,
            0x6064,
            0,
            Some(sdo::SdoType::Hex)
        )
        .unwrap(),
        Typing::Given(sdo::SdoType::Hex)
    );
    let run = |client: &mut gantry_cli::client::Client,
               object: &str,
               value: Option<&str>,
               ty: Option<sdo::SdoType>| {
        let mut out = Vec::new();
        let transfer = sdo::Transfer {
            target: Target::Axis("a0".into()),
            address: object,
            value,
            ty,
            timeout_s: None,
            file: None,
        };
        sdo::run(client, &transfer, false, &mut out)
            .map(|()| String::from_utf8(out).unwrap())
            .map_err(|e| e.to_string())
    };
    // An object the EDS does not have: refused, with or without --type.
    assert_eq!(
        run(&mut client, "0x2001:0", None, None).unwrap_err(),
        format!("0x2001:00 is not in {eds}")
    );
    let e = run(&mut client, "0x2001:0", Some("5"), Some(sdo::SdoType::U8)).unwrap_err();
    assert_eq!(e, format!("sdo: 0x2001:00 is not in {eds}"));
    // A value that does not fit the EDS' type, refused by the client.
    let e = run(&mut client, "0x6060:0", Some("300"), None).unwrap_err();
    assert!(
        e.starts_with("value \"300\" is not a INTEGER8, the object's type in its EDS"),
        "{e}"
    );
    // Writes the EDS says the drive would refuse: read-only, and the wrong width.
    let e = run(&mut client, "0x6041:0", Some("5"), None).unwrap_err();
    assert_eq!(
        e,
        format!("sdo: 0x6041:00 is ro in {eds}: it cannot be written")
    );
    let e = run(&mut client, "0x607A:0", Some("5"), Some(sdo::SdoType::U8)).unwrap_err();
    assert_eq!(
        e,
        format!("sdo: 0x607A:00 is a INTEGER32 of 4 bytes in {eds}; 1 bytes given")
    );
    drop(client);
    rt.shutdown_background();
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_node_that_is_not_the_device_of_its_eds_stops_the_bring_up() {
    let d = dir("identity");
    let text = simulated_servo_eds(&d);
    let product = text
        .lines()
        .find_map(|l| l.strip_prefix("ProductNumber="))
        .expect("the simulated EDS names its product")
        .to_string();
    std::fs::write(
        d.join("other.eds"),
        text.replace(
            &format!("ProductNumber={product}"),
            "ProductNumber=0x00000999",
        ),
    )
    .unwrap();
    // The configuration suits the other device's EDS (same objects)…
    let config = config(&d, &[3], "other.eds").unwrap_or_else(|e| panic!("{e}"));
    // …but node 3 says it is another product.
    let e = match CanRig::try_new(&config, servos(&[3])) {
        Ok(_) => panic!("the bus came up on a node that is not the EDS' device"),
        Err(e) => e.to_string(),
    };
    let read = eds::read(&text, "servo.eds")
        .unwrap()
        .device_info
        .product_number
        .unwrap();
    assert_eq!(
        e,
        format!(
            "CANopen node 3 (axis \"a0\"): its identity 0x1018:02 says product 0x{read:08X}, \
             {} describes product 0x00000999 (ProductNumber): not the device of that EDS",
            d.join("other.eds").display()
        )
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn the_switches_and_probe_layout_suits_the_simulators_eds_and_comes_up() {
    let d = dir("switches");
    simulated_servo_eds(&d);
    // The minimal layout with the drive's switches, the touch probe and its sources for
    // the limit switches (0x60BD too): 1 RPDO, 4 TPDOs; the EDS has 0x60D0 writable.
    let text = format!(
        "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\ncycle_us = 2000\n\
         [[axis]]\nname = \"x\"\nnode = 3\neds = \"servo.eds\"\npdo = \"csp-minimal\"\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
         max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n{}",
        gantry_tests::homing::AXIS_SWITCHES_TOML
    );
    let path = d.join("c.toml");
    std::fs::write(&path, text).unwrap();
    let config = Config::load(&path.display().to_string()).unwrap_or_else(|e| panic!("{e}"));
    let setup = gantry::canopen::bring_up::drive_setup(&config, 0).unwrap();
    assert_eq!((setup.plan.rpdos.len(), setup.plan.tpdos.len()), (1, 4));
    assert!(
        setup
            .steps
            .iter()
            .any(|s| (s.mux.index, s.mux.sub, s.value()) == (0x60D0, 2, &(-2i16).to_le_bytes()[..])),
        "0x60D0:2 written"
    );
    let mut rig = CanRig::new(&config, servos(&[3]));
    assert!(rig.log.contains("TPDO4"), "{}", rig.log);
    rig.enable_and_home(0);
    std::fs::remove_dir_all(&d).unwrap();
}
