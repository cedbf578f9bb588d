//! The encoder (CiA 406) and switch-cam input (CiA 401) nodes on the in-memory CAN bus:
//! the same modules as on EtherCAT behind the CiA 301 machinery of `CanNode` — boot-up,
//! SDO, NMT, TPDOs at SYNC, heartbeat — and the input module following a servo node on the
//! same bus to the count.

mod canopen_common;

use canopen_common::*;
use gantry_drives::canopen::nmt::NmtCommand;
use gantry_sim::canopen::{CanBus, CanDevice, CanNode, CanNodeConfig, DeviceKind, SlaveNodeError};
use gantry_sim::config::{SimConfig, SlaveConfig};
use gantry_sim::plant::switches::SwitchCam;

const REFERENCE: SwitchCam = SwitchCam {
    input: 0,
    from: 1000,
    to: 1999,
    normally_closed: false,
};
const POSITIVE_LIMIT: SwitchCam = SwitchCam {
    input: 1,
    from: 5000,
    to: i64::MAX,
    normally_closed: true,
};

fn u32_of(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// One 1 ms cycle: `rpdos`, then SYNC; the frames the nodes answered.
fn cycle(m: &mut Master, rpdos: &[gantry_drives::canopen::CanFrame]) -> Vec<(u16, Vec<u8>)> {
    m.step(MS);
    for f in rpdos {
        m.bus.send(*f);
    }
    let sync = m.sync_frame();
    m.send(&[sync]);
    m.take_inbox()
        .iter()
        .map(|d| (d.frame.id(), d.frame.data().to_vec()))
        .collect()
}

#[test]
fn the_encoder_node_counts_its_shaft_and_sends_the_position_value_at_sync() {
    let node = CanNode::new(CanNodeConfig::encoder(id(4), 4096, 0.5)).unwrap();
    let mut m = Master::with_nodes(vec![node]);
    m.step(0);
    assert_eq!(heartbeats(&m.take_inbox(), 4).len(), 1, "boot-up");
    // CiA 406 identity by SDO.
    assert_eq!(u32_of(&m.read(4, 0x1000, 0).unwrap()), 0x0005_0196);
    assert_eq!(m.read(4, 0x1008, 0).unwrap(), b"gantry-sim CiA 406 encoder");
    assert_eq!(u32_of(&m.read(4, 0x6001, 0).unwrap()), 4096);
    assert_eq!(u32_of(&m.read(4, 0x1018, 2).unwrap()), 0x5101);
    assert_eq!(u32_of(&m.read(4, 0x1A00, 1).unwrap()), 0x6004_0020);
    // The position value is read-only; the preset is no PDO object.
    assert!(m.write(4, 0x6004, 0, &1u32.to_le_bytes()).is_err());
    assert!(m
        .write(4, 0x1A01, 1, &0x6003_0020u32.to_le_bytes())
        .is_err());
    // Pre-operational: SYNC, no TPDO.
    assert!(cycle(&mut m, &[]).iter().all(|(id, _)| *id != 0x184));
    m.nmt(NmtCommand::Start, Some(4));
    m.take_inbox();
    let mut last = None;
    let mut seen = 0;
    for _ in 0..1000 {
        let got = cycle(&mut m, &[]);
        let tpdo: Vec<_> = got.iter().filter(|(id, _)| *id == 0x184).collect();
        assert_eq!(tpdo.len(), 1, "one TPDO1 per SYNC");
        let v = u32_of(&tpdo[0].1);
        // 0.5 rev/s at 4096 counts/rev: 2048 counts/s, whole counts of the shaft.
        let want = (2048.0 * m.now as f64 * 1e-9).floor() as i64;
        assert!((i64::from(v) - want).abs() <= 1, "{v} at {} ns", m.now);
        assert!(last.is_none_or(|l| v >= l), "counts forward");
        last = Some(v);
        seen += 1;
    }
    assert_eq!(seen, 1000);
    assert!(last.unwrap() >= 2040);
    // Preset (0x6003): the position value takes it when written, counting goes on.
    m.write(4, 0x6003, 0, &1_000_000u32.to_le_bytes()).unwrap();
    assert!((1_000_000..1_000_010).contains(&u32_of(&m.read(4, 0x6004, 0).unwrap())));
    let got = cycle(&mut m, &[]);
    let v = got
        .iter()
        .find(|(id, _)| *id == 0x184)
        .map(|(_, d)| u32_of(d));
    assert!(
        v.is_some_and(|v| (1_000_000..1_000_010).contains(&v)),
        "{v:?}"
    );
    // A heartbeat every 100 ms, Operational.
    for _ in 0..200 {
        m.step(MS);
    }
    let hb = heartbeats(&m.take_inbox(), 4);
    assert!(hb.len() >= 2, "{hb:?}");
    // A test can turn the shaft itself.
    if let CanDevice::Encoder(e) = m.node_mut(0).device_mut() {
        e.module_mut().drive(-1.0, 1.0);
    } else {
        panic!("not an encoder");
    }
    let got = cycle(&mut m, &[]);
    let v = got
        .iter()
        .find(|(id, _)| *id == 0x184)
        .map(|(_, d)| u32_of(d));
    assert!(
        v.is_some_and(|v| (1_000_000 - 4096 + 300..1_000_000 - 4096 + 500).contains(&v)),
        "{v:?}"
    );
}

#[test]
fn the_encoder_node_obeys_nmt() {
    let node = CanNode::new(CanNodeConfig::encoder(id(6), 1000, 1.0)).unwrap();
    let mut m = Master::with_nodes(vec![node]);
    m.step(0);
    m.nmt(NmtCommand::Start, Some(6));
    for _ in 0..500 {
        cycle(&mut m, &[]);
    }
    m.write(6, 0x6003, 0, &7u32.to_le_bytes()).unwrap();
    // Stopped: no TPDO at SYNC, no SDO answer (CiA 301 Table 41).
    m.nmt(NmtCommand::Stop, Some(6));
    m.take_inbox();
    assert!(cycle(&mut m, &[]).iter().all(|(id, _)| *id != 0x186));
    assert!(m.read(6, 0x6004, 0).is_err(), "no SDO in Stopped");
    // Reset node: boot-up, pre-operational; the counter restarts at 0 and the preset
    // object reads its power-on 0; the shaft (1 rev/s, 1000 counts/rev) turned on.
    m.take_inbox();
    let at_reset = m.now;
    m.nmt(NmtCommand::ResetNode, Some(6));
    let boot = heartbeats(&m.take_inbox(), 6);
    assert_eq!(boot.len(), 1, "{boot:?}");
    assert_eq!(u32_of(&m.read(6, 0x6003, 0).unwrap()), 0);
    let since = (m.now - at_reset) as f64 * 1e-6;
    let v = i64::from(u32_of(&m.read(6, 0x6004, 0).unwrap()));
    assert!(
        (v - since as i64).abs() <= 2,
        "{v} counts {since} ms after the reset"
    );
    m.nmt(NmtCommand::Start, Some(6));
    m.take_inbox();
    assert!(cycle(&mut m, &[]).iter().any(|(id, _)| *id == 0x186));
}

/// Enables servo node 1 (CiA 402 transitions 2, 3, 4) holding 0, moves it to 6000 counts
/// at 4 counts/ms and back to 1500, one 1 ms cycle (RPDO1, SYNC) at a time; `each` gets
/// the position the servo's TPDO1 reported at each SYNC and every frame of that cycle.
/// Returns the last statusword and position.
fn move_servo(m: &mut Master, mut each: impl FnMut(i32, &[(u16, Vec<u8>)])) -> (u16, i32) {
    let mut sw = 0u16;
    let mut pos = 0i32;
    let plan = (0..40)
        .map(|_| 0)
        .chain((0..=1500).map(|k| 4 * k))
        .chain((0..1125).map(|k| 6000 - 4 * k))
        .chain((0..50).map(|_| 1500));
    for step in plan {
        let cw: u16 = match sw & 0x6F {
            0x21 => 0x07,
            0x23 | 0x27 => 0x0F,
            _ => 0x06,
        };
        let target = if sw & 0x6F == 0x27 { step } else { pos };
        let mut d = [0u8; 6];
        d[..2].copy_from_slice(&cw.to_le_bytes());
        d[2..].copy_from_slice(&target.to_le_bytes());
        let got = cycle(m, &[frame(0x201, &d)]);
        let servo_tpdo = got.iter().find(|(id, _)| *id == 0x181).expect("servo TPDO");
        sw = u16::from_le_bytes([servo_tpdo.1[0], servo_tpdo.1[1]]);
        pos = i32::from_le_bytes(servo_tpdo.1[2..6].try_into().unwrap());
        each(pos, &got);
    }
    (sw, pos)
}

/// Expected input byte at `position` with the two cams.
fn levels(position: i64) -> u8 {
    u8::from(REFERENCE.level(position)) | (u8::from(POSITIVE_LIMIT.level(position)) << 1)
}

#[test]
fn the_input_module_follows_the_servo_on_the_same_bus_to_the_count() {
    let servo = CanNode::new(CanNodeConfig::servo(id(1))).unwrap();
    let inputs =
        CanNode::new(CanNodeConfig::switches(id(2), id(1), &[REFERENCE, POSITIVE_LIMIT]).unwrap())
            .unwrap();
    // The module first on the bus: the delivery order, not the bus order, makes it
    // sample after the servo.
    let mut m = Master::with_nodes(vec![]);
    m.bus = CanBus::new(vec![inputs, servo]).with_bitrate(1_000_000);
    m.step(0);
    assert_eq!(u32_of(&m.read(2, 0x1000, 0).unwrap()), 0x0001_0191);
    assert_eq!(m.read(2, 0x6000, 0).unwrap(), [1]);
    assert_eq!(u32_of(&m.read(2, 0x1A00, 1).unwrap()), 0x6000_0108);
    m.nmt(NmtCommand::Start, None);
    m.take_inbox();
    let mut checked = 0;
    let mut seen_levels = std::collections::BTreeSet::new();
    let (sw, pos) = move_servo(&mut m, |pos, got| {
        let input_tpdo = got
            .iter()
            .find(|(id, _)| *id == 0x182)
            .expect("inputs TPDO");
        // The inputs sampled at this SYNC are the cams at the position the servo
        // reported at this SYNC.
        assert_eq!(input_tpdo.1, [levels(i64::from(pos))], "at {pos}");
        seen_levels.insert(input_tpdo.1[0]);
        checked += 1;
    });
    assert_eq!(sw & 0x6F, 0x27, "operation enabled");
    assert!((pos - 1500).abs() <= 2, "{pos}");
    assert!(checked > 2600);
    // Reference switch on and off, limit reached: every combination on the way.
    assert_eq!(
        seen_levels.into_iter().collect::<Vec<_>>(),
        vec![0b00, 0b10, 0b11],
        "limit NC: high below 5000; reference 1000..=1999"
    );
    // Polarity 0x6002:01 inverts input 0 (CiA 401).
    m.write(2, 0x6002, 1, &[0x01]).unwrap();
    let got = cycle(&mut m, &[]);
    let input = got.iter().find(|(id, _)| *id == 0x182).unwrap();
    assert_eq!(input.1, [levels(1500) ^ 0x01]);
}

#[test]
fn event_driven_inputs_are_sent_when_a_cam_switches() {
    let servo = CanNode::new(CanNodeConfig::servo(id(1))).unwrap();
    let inputs =
        CanNode::new(CanNodeConfig::switches(id(2), id(1), &[REFERENCE, POSITIVE_LIMIT]).unwrap())
            .unwrap();
    let mut m = Master::with_nodes(vec![servo, inputs]);
    m.step(0);
    // TPDO1 event-driven (transmission type 255, CiA 401's default for inputs): sent when
    // the input byte changes, not at SYNC.
    m.write(2, 0x1800, 2, &[255]).unwrap();
    m.nmt(NmtCommand::Start, None);
    m.step(MS);
    let first: Vec<_> = on(&m.take_inbox(), 0x182);
    assert_eq!(
        first.len(),
        1,
        "the first event: the first run in Operational"
    );
    assert_eq!(first[0].data(), [levels(0)]);
    let mut sent = Vec::new();
    let mut last_level = levels(0);
    let mut changes = 0;
    let (sw, _) = move_servo(&mut m, |pos, got| {
        let level = levels(i64::from(pos));
        if level != last_level {
            changes += 1;
            last_level = level;
        }
        for (_, d) in got.iter().filter(|(id, _)| *id == 0x182) {
            // Sent in the cycle the servo reached the position that switched it.
            assert_eq!(d, &[level], "at {pos}");
            sent.push(d[0]);
        }
    });
    assert_eq!(sw & 0x6F, 0x27);
    // 0 -> 6000 -> 1500: reference on, off, limit on, off, reference on.
    assert_eq!(changes, 5);
    assert_eq!(sent, [0b11, 0b10, 0b00, 0b10, 0b11]);
}

#[test]
fn a_module_whose_servo_is_not_on_the_bus_reads_its_cams_at_rest() {
    let inputs =
        CanNode::new(CanNodeConfig::switches(id(2), id(9), &[REFERENCE, POSITIVE_LIMIT]).unwrap())
            .unwrap();
    let mut m = Master::with_nodes(vec![inputs]);
    m.step(0);
    m.nmt(NmtCommand::Start, None);
    m.take_inbox();
    let got = cycle(&mut m, &[]);
    // No position ever: nothing actuated, the NC limit reads high.
    assert_eq!(got.iter().find(|(id, _)| *id == 0x182).unwrap().1, [0b10]);
}

#[test]
fn nodes_are_built_from_the_chain_description() {
    let text = r#"
[[slave]]
kind = "servo"
node = 1
start_position = 1500

[[slave]]
kind = "encoder"
node = 5
counts_per_rev = 1024

[[slave]]
kind = "switches"
node = 7
axis = 0
[[slave.cam]]
input = 0
from = 1000
to = 1999
"#;
    let c = SimConfig::parse(text, "chain.toml").unwrap();
    let nodes: Vec<CanNode> = (0..3)
        .map(|i| CanNode::new(CanNodeConfig::from_slave(&c, i).unwrap()).unwrap())
        .collect();
    let kinds: Vec<_> = nodes.iter().map(|n| n.dictionary().kind()).collect();
    assert_eq!(
        kinds,
        [DeviceKind::Servo, DeviceKind::Encoder, DeviceKind::Switches]
    );
    assert_eq!(nodes[2].coupled_axis(), Some(id(1)));
    let mut m = Master::with_nodes(nodes);
    m.step(0);
    assert_eq!(u32_of(&m.read(5, 0x6001, 0).unwrap()), 1024);
    m.nmt(NmtCommand::Start, None);
    m.take_inbox();
    let got = cycle(&mut m, &[]);
    // The servo powered up at 1500: the reference cam is actuated.
    assert_eq!(got.iter().find(|(id, _)| *id == 0x187).unwrap().1, [0b1]);
    // What cannot be a node.
    assert_eq!(
        CanNodeConfig::from_slave(&c, 3),
        Err(SlaveNodeError::NoSlave { index: 3 })
    );
    // (The configuration refuses an axis that is no servo; a hand-made one is refused
    // here too.)
    let mut bad_axis = c.clone();
    if let Some(SlaveConfig::Switches { axis, .. }) = bad_axis.slaves.get_mut(2) {
        *axis = 1;
    }
    assert_eq!(
        CanNodeConfig::from_slave(&bad_axis, 2)
            .unwrap_err()
            .to_string(),
        "slave[2].axis = 1 is not a servo"
    );
    let no_node = text.replace("node = 1\n", "");
    let c = SimConfig::parse(&no_node, "chain.toml").unwrap();
    assert_eq!(
        CanNodeConfig::from_slave(&c, 0),
        Err(SlaveNodeError::NoNodeId { index: 0 })
    );
    assert_eq!(
        CanNodeConfig::from_slave(&c, 2).unwrap_err().to_string(),
        "slave[2].axis = 0: that servo has no CANopen node id"
    );
}
