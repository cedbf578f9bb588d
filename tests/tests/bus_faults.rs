//! Bus faults, lockstep (one thread; ethercrab's PDU timeout is 20 ms of wall time): lost
//! frames are ridden through up to the limit, then every axis stops with the reason; a
//! slave that disappears mid-move stops its own axis while the others finish; plugged back
//! in, it returns to OP on a reset and its axis moves again. The reasons reach the user as
//! text.

use std::time::Duration;

use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup, Timeouts};
use gantry::axis_fault::describe_fault;
use gantry::ethercat::health::{BusHealth, Exchange, HealthConfig, States};
use gantry::ethercat::recovery::{access, Recovered, Recovery, RecoveryError, RECOVERY_TIMEOUT_NS};
use gantry::runtime::cycle::Cycle;
use gantry::runtime::cycle::COMMUNICATION_FAULT;
use gantry_drives::csp::CspChannel;
use gantry_kernel::axis::command::{Command, CommandError, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_tests::ball_screw_5mm;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::lockstep::Lockstep;
use gantry_tests::servo_chain;

const DRIVES: usize = 3;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();
type Group = SubDeviceGroup<4, 64, ethercrab::DefaultLock, Op>;

struct Machine {
    net: Lockstep,
    md: MainDevice<'static>,
    group: Group,
    cycle: Cycle,
    health: BusHealth,
}

impl Machine {
    fn new() -> Self {
        let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().unwrap();
        // Drives as the simulator makes them: their firmware takes 5 ms from SafeOp to Op
        // and waits for valid outputs, so a reset polls across cycles (`recover`).
        let chain = servo_chain(DRIVES as u32);
        let mut net = Lockstep::new(tx, rx, chain);
        let timeouts = Timeouts {
            pdu: Duration::from_millis(20),
            ..gantry_tests::lockstep_timeouts()
        };
        let md = MainDevice::new(pdu_loop, timeouts, MainDeviceConfig::default());
        let group: Group = net.group_in_op(&md).unwrap();
        let addresses = group.iter(&md).map(|sd| sd.configured_address()).collect();
        let axes = (0..DRIVES)
            .map(|i| AxisConfig::new(&format!("a{i}"), AxisKind::Real))
            .collect();
        let cycle = Cycle::new(
            Kernel::new(1e-3, axes).unwrap(),
            vec![CspChannel::new(ball_screw_5mm()); DRIVES],
        );
        let health = BusHealth::new(
            HealthConfig::default(),
            addresses,
            // Each servo has inputs and outputs: 1 + 2 in the LRW (ETG.1000.4 §5.4.3).
            vec![3; DRIVES],
        );
        Self {
            net,
            md,
            group,
            cycle,
            health,
        }
    }

    fn cycle(&mut self) {
        for i in 0..DRIVES {
            if self.health.fault(i).is_some() {
                self.cycle.comm_fault(i).unwrap();
            } else {
                let sd = self.group.subdevice(&self.md, i).unwrap();
                self.cycle.read_inputs(i, &sd.inputs_raw()).unwrap();
            }
        }
        self.cycle.step();
        for i in 0..DRIVES {
            let sd = self.group.subdevice(&self.md, i).unwrap();
            self.cycle
                .write_outputs(i, sd.io_raw_mut().outputs())
                .unwrap();
        }
        match self.net.block_on(self.group.tx_rx(&self.md)) {
            Ok(r) => self.health.record(Exchange::Answered {
                working_counter: r.working_counter,
                states: States::Each(&r.subdevice_states),
            }),
            Err(_) => self.health.record(Exchange::Lost),
        }
        self.net.chain.tick(1e-3);
    }

    /// Brings slave `i` back to OP as the engine does: one register access per cycle,
    /// the process data running meanwhile (a drive goes to Op only with valid outputs),
    /// time injected (1 ms per cycle).
    fn recover(&mut self, i: usize) -> (Result<Recovered, RecoveryError>, u32) {
        let address = self
            .group
            .subdevice(&self.md, i)
            .unwrap()
            .configured_address();
        let mut recovery = Recovery::new(address, 0, RECOVERY_TIMEOUT_NS);
        for cycles in 1.. {
            let next = recovery.next_access().unwrap();
            let sd = self.group.subdevice(&self.md, i).unwrap();
            let answer = self.net.block_on(access(&sd, next));
            self.cycle();
            recovery.on_answer(answer, u64::from(cycles) * 1_000_000);
            if let Some(outcome) = recovery.outcome() {
                return (outcome, cycles);
            }
        }
        unreachable!("the recovery times out")
    }

    fn run(&mut self, n: usize) {
        for _ in 0..n {
            self.cycle();
        }
    }

    fn command(&mut self, i: usize, cmd: Command) -> HandleId {
        self.cycle.kernel.command(i, cmd).unwrap()
    }

    fn move_to(&mut self, i: usize, to: f64) -> HandleId {
        self.command(
            i,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, to)),
        )
    }

    fn status(&self, h: HandleId) -> CommandStatus {
        self.cycle.kernel.command_status(h)
    }

    fn state(&self, i: usize) -> AxisState {
        self.cycle.kernel.axis_status(i).unwrap().state
    }

    fn actual(&self, i: usize) -> f64 {
        self.cycle.kernel.axis_status(i).unwrap().actual_position
    }
}

#[test]
fn lost_frames_and_a_lost_slave_stop_what_they_must_and_recover_on_reset() {
    let mut m = Machine::new();
    for i in 0..DRIVES {
        m.command(i, Command::Power(PowerCommand::Enable));
    }
    m.run(20);
    for i in 0..DRIVES {
        assert_eq!(m.state(i), AxisState::Standstill);
        m.command(
            i,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        );
    }

    // Two frames lost mid-move: ridden through, the moves finish.
    let moves: Vec<_> = (0..DRIVES).map(|i| m.move_to(i, 30.0)).collect();
    m.run(50);
    m.net.chain.drop_frames(2);
    m.run(600);
    for (i, h) in moves.iter().enumerate() {
        assert_eq!(m.status(*h), CommandStatus::Done, "axis {i}");
        assert!((m.actual(i) - 30.0).abs() < 0.01);
    }
    assert_eq!(m.health.lost_total, 2);

    // Five in a row (limit 3): every axis stops, with the reason.
    let moves: Vec<_> = (0..DRIVES).map(|i| m.move_to(i, 0.0)).collect();
    m.run(50);
    m.net.chain.drop_frames(5);
    m.run(10);
    let reason = m.health.fault(0).map(|f| f.to_string());
    assert_eq!(
        reason.as_deref(),
        Some("EtherCAT: 3 frames lost in a row (limit 3)")
    );
    for (i, h) in moves.iter().enumerate() {
        assert_eq!(m.state(i), AxisState::ErrorStop, "axis {i}");
        assert!(
            matches!(
                m.status(*h),
                CommandStatus::Error(CommandError::AxisFault { .. })
            ),
            "axis {i}: the move ends in error"
        );
        let error = m.cycle.kernel.axis_status(i).unwrap().error.unwrap();
        assert_eq!(
            describe_fault(&error),
            format!(
                "drive fault 0x{COMMUNICATION_FAULT:04X}: communication error (the master cannot reach the drive)"
            )
        );
    }
    // Reset: the slaves never left OP (5 ms < their 100 ms watchdog), the drives stayed
    // enabled: the axes are back at once and finish the move.
    for i in 0..DRIVES {
        assert_eq!(m.recover(i), (Ok(Recovered::WasInOp), 1));
    }
    m.health.clear();
    m.run(2);
    for i in 0..DRIVES {
        let h = m.command(i, Command::Reset);
        assert_eq!(m.status(h), CommandStatus::Done);
        assert_eq!(m.state(i), AxisState::Standstill);
    }
    let moves: Vec<_> = (0..DRIVES).map(|i| m.move_to(i, 0.0)).collect();
    m.run(600);
    for h in &moves {
        assert_eq!(m.status(*h), CommandStatus::Done);
    }

    // Slave 2's cable pulled mid-move for 150 ms: its axis stops with the reason, the
    // others finish their moves.
    let moves: Vec<_> = (0..DRIVES).map(|i| m.move_to(i, 30.0)).collect();
    m.run(50);
    m.net.chain.cut_before(Some(2));
    m.run(150);
    assert_eq!(
        m.health.fault(2).map(|f| f.to_string()).as_deref(),
        Some("EtherCAT: slave 2 (0x1002) does not answer (cable, power?)")
    );
    assert_eq!(m.state(2), AxisState::ErrorStop);
    assert!(matches!(
        m.status(moves[2]),
        CommandStatus::Error(CommandError::AxisFault { .. })
    ));
    m.net.chain.cut_before(None);
    m.run(450);
    for (i, h) in moves.iter().enumerate().take(2) {
        assert_eq!(m.status(*h), CommandStatus::Done, "axis {i} went on");
        assert!((m.actual(i) - 30.0).abs() < 0.01);
    }
    // Back on the wire, the slave is in SafeOp with its watchdog error, the drive faulted.
    assert_eq!(m.net.chain.slaves()[2].al_status(), 0x14);
    let (outcome, cycles) = m.recover(2);
    assert_eq!(outcome, Ok(Recovered::BackInOp));
    // Read, acknowledge, read, request Op, then reads through the drive's 5 ms.
    assert!(cycles >= 8, "back in Op after {cycles} cycles");
    assert_eq!(m.net.chain.slaves()[2].al_status(), 0x08);
    m.health.clear();
    let reset = m.command(2, Command::Reset);
    m.run(20);
    assert_eq!(m.status(reset), CommandStatus::Done);
    assert_eq!(m.state(2), AxisState::Disabled);
    m.command(2, Command::Power(PowerCommand::Enable));
    m.run(20);
    let h = m.move_to(2, 30.0);
    m.run(600);
    assert_eq!(m.status(h), CommandStatus::Done);
    assert!((m.actual(2) - 30.0).abs() < 0.01);
    // Lost frames and a cut cable fault drives (0x8700), not their following error; and
    // no target that reached a drive stepped further than the axis' speed allows.
    let drives = DriveUnderTest::of_kernel(&m.cycle.kernel, |_| ball_screw_5mm());
    assert_drive_invariants(&m.net.chain, &drives, 1e-3, TestConditions::default());
}
