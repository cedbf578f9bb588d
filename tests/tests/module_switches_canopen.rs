//! Switches on a CANopen I/O module, in lockstep (`gantry_tests::can_rig`): a simulated
//! CiA 402 servo (node 5) and the simulator's CiA 401 switch-cam input module (node 9)
//! whose inputs are cams on the servo's travel; the axis names them
//! `{ from = "module", node = 9, input = K }`. The bus brings the module up with the
//! drive (boot-up, 0x1000 = 401, TPDO1 = 0x6000:01 on SYNC, heartbeat, NMT start), the
//! cycle reads its inputs every cycle and routes them to the axis as on EtherCAT
//! (`gantry_tests::homing::module_scenario`, the scenario of `module_switches_ethercat.rs`),
//! and a module the bus loses stops the axis, naming the node.

use gantry::runtime::bus::Restored;
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::NodeId;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::AxisFault;
use gantry_sim::canopen::nmt::NmtSlaveState;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_sim::config::SimConfig;
use gantry_tests::can_rig::{servos, CanRig};
use gantry_tests::homing::{
    module_scenario, module_switches_toml, HomingRig, AXIS_MODULE_SWITCHES_TOML,
};
use gantry_tests::servo_rig::{CanopenServo, ServoRig};

const SERVO: u8 = 5;
const MODULE: u8 = 9;
/// The communication fault gantry gives an axis it cannot reach (CiA 402 0x8100).
const COMMUNICATION_FAULT: u16 = 0x8100;

/// The servo (without switches of its own) and the switch-cam module watching it.
fn nodes() -> Vec<CanNode> {
    let chain = SimConfig::parse(
        &format!(
            "[[slave]]\nkind = \"servo\"\nnode = {SERVO}\n{}",
            module_switches_toml().replacen(
                "axis = 0\n",
                &format!("axis = 0\nnode = {MODULE}\n"),
                1
            )
        ),
        "sim.toml",
    )
    .expect("chain");
    (0..2)
        .map(|i| CanNode::new(CanNodeConfig::from_slave(&chain, i).expect("node")).expect("node"))
        .collect()
}

/// The axis on node 5, its switches on module node 9 (inputs 2 and 1 the normally closed
/// limit switches, 0 the home cam).
fn config() -> gantry::config::Config {
    gantry::config::Config::parse(&config_text(), "can.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// [`config`]'s text.
fn config_text() -> String {
    let switches = AXIS_MODULE_SWITCHES_TOML.replace("slave = 1", &format!("node = {MODULE}"));
    assert_ne!(switches, AXIS_MODULE_SWITCHES_TOML);
    format!(
        "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\ncycle_us = 2000\n\
             [[axis]]\nname = \"x\"\nnode = {SERVO}\npdo = \"csp-minimal\"\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 40000.0 }}\n{switches}"
    )
}

/// The servo's rig; its module is node [`MODULE`] on the same bus.
type CanopenModule = CanopenServo;

fn enabled() -> CanopenModule {
    let mut rig = CanopenServo {
        rig: CanRig::new(&config(), nodes()),
        node: SERVO,
        cycle_s: 2e-3,
    };
    assert_eq!(
        rig.run_command(Command::Power(PowerCommand::Enable), 5000),
        CommandStatus::Done
    );
    rig
}

#[test]
fn switches_on_a_canopen_io_module_reach_the_axis_and_stop_it() {
    let mut rig = enabled();
    let log = rig.rig.log.clone();
    assert!(
        log.contains("node 9 (I/O module of x): CiA 401 device type 0x00010191"),
        "{log}"
    );
    // Its TPDO1 maps 0x6000:01 from power-on (CiA 401's default): taken as it is.
    assert!(
        log.contains("node 9: TPDO1 taken as its CiA 401 default mapping (0x6000:01..=01)"),
        "{log}"
    );
    assert!(log.contains("node 9: , TPDO1 1 bytes"), "{log}");
    assert!(log.contains("2 nodes operational"), "{log}");
    // The module is Operational, its TPDO1 the inputs on SYNC (transmission type 1).
    {
        let mut sim = rig.rig.sim();
        let mut tt = [0u8; 1];
        sim.node_mut(MODULE)
            .read_object(0x1800, 2, &mut tt)
            .expect("0x1800:02");
        assert_eq!(tt, [1]);
        assert_eq!(format!("{:?}", sim.node(MODULE).nmt_state()), "Operational");
    }
    // The drive maps no 0x60FD: the switches come from the module only.
    assert!(!config().axes[0]
        .pdo_layout()
        .expect("layout")
        .inputs
        .iter()
        .any(|o| o.index == 0x60FD));
    // Both limit switches are normally closed: at 0 neither input is low, none active;
    // the module's raw inputs say both contacts are closed (bits 1 and 2 high).
    let sw = rig.status().switches;
    assert!(!sw.negative_limit && !sw.positive_limit && !sw.reference);
    let raw = gantry::runtime::bus::CycleBus::inputs(&rig.rig.engine.bus, 1).to_vec();
    assert_eq!(raw, [0b110], "module inputs at 0 mm");
    // The status shows it (the snapshot the CLI's `gantry status` prints).
    rig.cycles(2);
    let snap = rig.rig.snapshot();
    assert!(!snap.axes[0].switches.positive_limit);
    module_scenario(&mut rig);
    assert_eq!(rig.rig.engine.bus.malformed(), 0);
    // At shutdown the module leaves the cycle with the drive: pre-operational, its
    // watches of gantry's SYNC and heartbeat taken back.
    let (out, bus) = rig.rig.shut_down(5000);
    assert!(out.contains("taken back on node(s) 5, 9 in"), "{out}");
    assert_eq!(
        gantry_tests::can_rig::lock(&bus).node(MODULE).nmt_state(),
        NmtSlaveState::PreOperational
    );
}

/// Module loss: its heartbeat silent past the consumer time stops the axis (ErrorStop,
/// communication fault) with the module's node named in the status; the drive itself is
/// fine. Once the module is heard again, a reset brings it back (NMT reset, its
/// configuration, NMT start) and the axis moves again. Then a module that reset itself
/// (its boot-up) and a lost TPDO do the same.
#[test]
fn a_lost_or_silent_io_module_stops_its_axis_naming_the_module() {
    let mut rig = enabled();
    let here = Command::SetPosition {
        position: 0.0,
        relative: false,
    };
    assert_eq!(rig.run_command(here, 100), CommandStatus::Done);
    let to = |p: f64| Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, p).speed(20.0));
    let h = rig.rig.ctl.command(0, to(30.0)).expect("queued");
    rig.cycles(50);
    // The module's heartbeats (0x709) no longer reach gantry.
    rig.rig.sim().drop_frames(0x700 + u16::from(MODULE), true);
    let mut cycles = 0;
    while rig.rig.bus_fault(0).is_none() {
        rig.rig.cycle();
        cycles += 1;
        assert!(cycles < 300, "no fault after {cycles} cycles");
    }
    let reason = rig.rig.bus_fault(0).expect("fault");
    assert!(
        reason.starts_with("switch module: CANopen node 9: no heartbeat for ")
            && reason.ends_with(" ms (limit 300 ms)"),
        "{reason}"
    );
    rig.cycles(5);
    assert_eq!(rig.status().state, AxisState::ErrorStop);
    assert_eq!(
        rig.status().error,
        Some(AxisFault::Drive {
            code: COMMUNICATION_FAULT
        })
    );
    assert!(matches!(
        rig.rig.engine.command_status(h.id()),
        Some(CommandStatus::Aborted | CommandStatus::Error(_))
    ));
    // The status names the module (the snapshot is published every few cycles).
    rig.cycles(20);
    let snap = rig.rig.snapshot();
    let shown = snap.drives[0]
        .bus_fault
        .map(|f| f.to_string())
        .unwrap_or_default();
    assert!(shown.contains("switch module: CANopen node 9"), "{shown}");
    // Not the drive's own fault: its node is fine.
    assert!(
        gantry::runtime::bus::CycleBus::can_node(&rig.rig.engine.bus, 0)
            .is_some_and(|n| n.lost_in_a_row == 0 && n.nmt == Some("Operational"))
    );
    // Heard again, a reset brings the module back and the axis runs.
    rig.rig.sim().drop_frames(0x700 + u16::from(MODULE), false);
    reset_enable_move(&mut rig, 5.0);

    // The module resets itself (NMT reset node from another tool): its boot-up faults
    // the axis, naming it; a reset configures it again.
    let reset_node = NmtFrame {
        command: NmtCommand::ResetNode,
        target: NmtTarget::Node(NodeId::new(MODULE).expect("id")),
    }
    .emit();
    rig.rig.sim().inject(reset_node);
    let mut cycles = 0;
    while rig.rig.bus_fault(0).is_none() {
        rig.rig.cycle();
        cycles += 1;
        assert!(cycles < 50, "no fault after {cycles} cycles");
    }
    let reason = rig.rig.bus_fault(0).expect("fault");
    assert!(
        reason.starts_with("switch module: CANopen node 9: ")
            && (reason.contains("boot-up") || reason.contains("no TPDO")),
        "{reason}"
    );
    rig.cycles(5);
    assert_eq!(rig.status().state, AxisState::ErrorStop);
    reset_enable_move(&mut rig, 0.0);

    // Its TPDO lost three cycles in a row ([bus.faults] lost_frames_limit).
    rig.rig.sim().drop_frames(0x180 + u16::from(MODULE), true);
    rig.cycles(2);
    assert_eq!(rig.rig.bus_fault(0), None, "two lost: ridden through");
    rig.rig.cycle();
    assert_eq!(
        rig.rig.bus_fault(0).as_deref(),
        Some("switch module: CANopen node 9: no TPDO for 3 cycles in a row")
    );
    rig.cycles(3);
    assert_eq!(rig.status().state, AxisState::ErrorStop);
    rig.rig.sim().drop_frames(0x180 + u16::from(MODULE), false);
    reset_enable_move(&mut rig, 5.0);
    assert_eq!(
        rig.drive_faults(),
        0,
        "the drive never faulted: only its axis stopped"
    );

    // The drive and the module both reset by another tool: one reset brings both back,
    // the drive first, then the module.
    for node in [SERVO, MODULE] {
        let reset_node = NmtFrame {
            command: NmtCommand::ResetNode,
            target: NmtTarget::Node(NodeId::new(node).expect("id")),
        }
        .emit();
        rig.rig.sim().inject(reset_node);
    }
    rig.cycles(20);
    assert_eq!(rig.status().state, AxisState::ErrorStop);
    let faulted = |rig: &CanopenModule, i| {
        gantry::runtime::bus::CycleBus::fault(&rig.rig.engine.bus, i).map(|f| f.to_string())
    };
    let drive = faulted(&rig, 0).expect("the drive's own fault");
    assert!(drive.starts_with("CANopen node 5: "), "{drive}");
    let module = faulted(&rig, 1).expect("the module's fault");
    assert!(
        module.starts_with("switch module: CANopen node 9: "),
        "{module}"
    );
    reset_enable_move(&mut rig, 0.0);
    assert_eq!(
        rig.rig.sim().node(SERVO).nmt_state(),
        NmtSlaveState::Operational
    );
}

/// Reset (bringing the module back), enable when the reset left the axis disabled, and
/// a move to `to` that ends Done.
fn reset_enable_move(rig: &mut CanopenModule, to: f64) {
    let h = rig.rig.ctl.reset(0).expect("queued");
    let status = rig.rig.finish(&h, 5000);
    assert_eq!(status, CommandStatus::Done, "{:?}", rig.rig.bus_fault(0));
    assert_eq!(rig.rig.bus_fault(0), None);
    // The module was brought back by the bus (its drive was fine).
    let restore = rig.rig.engine.last_restore().expect("a restore");
    assert_eq!(
        restore.outcome,
        Ok(Restored::BackInOperation),
        "{restore:?}"
    );
    assert!(
        restore.cycles > 3,
        "NMT reset, boot-up, SDO writes: {restore:?}"
    );
    assert_eq!(
        rig.rig.sim().node(MODULE).nmt_state(),
        NmtSlaveState::Operational
    );
    if rig.status().state == AxisState::Disabled {
        assert_eq!(
            rig.run_command(Command::Power(PowerCommand::Enable), 5000),
            CommandStatus::Done
        );
    }
    let mv = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, to).speed(20.0));
    assert_eq!(rig.run_command(mv, 10_000), CommandStatus::Done);
    assert_eq!(rig.status().state, AxisState::Standstill);
}

/// A node named as an I/O module that is not one, or that does not boot: the bus does not
/// come up, and says which node and why.
#[test]
fn the_bring_up_refuses_a_module_node_that_is_not_a_cia_401_module_or_is_missing() {
    // Node 9 is a servo.
    let mut wrong = servos(&[SERVO, MODULE]);
    let e = CanRig::try_new(&config(), std::mem::take(&mut wrong))
        .err()
        .expect("refused")
        .to_string();
    assert_eq!(
        e,
        "CANopen node 9 (I/O module of x): device type 0x00020192 is profile 402, not a CiA \
         401 I/O module (0x1000 bits 0–15 = 401)"
    );
    // No node 9.
    let e = CanRig::try_new(&config(), servos(&[SERVO]))
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.starts_with("CANopen: no boot-up from node 9 within"),
        "{e}"
    );
}

/// A module without 0x1016 (the heartbeat consumer is optional, CiA 301 §7.5.2.16):
/// its refusal (abort 0x06020000, object does not exist) is taken — an input module has
/// no outputs to make safe when gantry stops — and the bus comes up without it; any other
/// refusal stops the bring-up (the tests above).
#[test]
fn a_module_without_a_heartbeat_consumer_comes_up_without_it() {
    use gantry::canopen::{CanLink, CanopenBus, Received};
    use gantry_drives::canopen::CanFrame;
    use gantry_tests::can_rig::MemLink;

    /// The module's SDO server as one without 0x1016: a download to it is aborted.
    struct No1016 {
        inner: MemLink,
        abort: Option<CanFrame>,
    }
    impl CanLink for No1016 {
        fn send(&mut self, frame: &CanFrame) -> std::io::Result<()> {
            let d = frame.data();
            // Client command specifier 1: initiate download (CiA 301 §7.2.4.3.3).
            if frame.id() == 0x600 + u16::from(MODULE)
                && d.first().is_some_and(|b| b >> 5 == 1)
                && d.get(1..3) == Some(&[0x16, 0x10][..])
            {
                let mut abort = [0x80, 0x16, 0x10, d[3], 0, 0, 0, 0];
                abort[4..].copy_from_slice(&0x0602_0000u32.to_le_bytes());
                self.abort = CanFrame::new(0x580 + u32::from(MODULE), &abort).ok();
                return Ok(());
            }
            self.inner.send(frame)
        }
        fn receive(&mut self, deadline_ns: u64) -> std::io::Result<Option<Received>> {
            if let Some(frame) = self.abort.take() {
                return Ok(Some(Received {
                    frame,
                    at_ns: Some(self.inner.now_ns()),
                }));
            }
            self.inner.receive(deadline_ns)
        }
        fn now_ns(&self) -> u64 {
            self.inner.now_ns()
        }
    }
    let (inner, sim) = MemLink::new(nodes(), Some(1_000_000));
    let link = No1016 { inner, abort: None };
    let mut log = Vec::new();
    let bus = CanopenBus::bring_up_on(&config(), Box::new(link), &mut log)
        .unwrap_or_else(|e| panic!("{}", gantry::error_chain::Chain(&e)));
    let log = String::from_utf8_lossy(&log);
    assert!(
        log.contains("node 9: has no 0x1016 (optional): not set"),
        "{log}"
    );
    assert!(log.contains("2 nodes operational"), "{log}");
    // The drive took its consumer of gantry's heartbeat; the module was not given one.
    let mut s = gantry_tests::can_rig::lock(&sim);
    let mut consumer = [0u8; 4];
    s.node_mut(SERVO)
        .read_object(0x1016, 1, &mut consumer)
        .expect("0x1016:01");
    assert_eq!(u32::from_le_bytes(consumer) >> 16, 127, "gantry's node id");
    s.node_mut(MODULE)
        .read_object(0x1016, 1, &mut consumer)
        .expect("0x1016:01");
    assert_eq!(u32::from_le_bytes(consumer), 0);
    drop(s);
    assert_eq!(gantry::runtime::bus::CycleBus::drives(&bus), 2);
}
