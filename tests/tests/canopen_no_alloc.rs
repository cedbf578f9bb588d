//! The CANopen bus allocates nothing in the cycle: a counting allocator watches every
//! engine cycle (the bus' exchange — RPDOs, SYNC, TPDOs, heartbeats, EMCYs — the kernel,
//! the drive layer, and the restore's NMT and SDO steps) while four simulated drives are
//! enabled and moved, a node's heartbeat stays away until its axis stops, the node is
//! reset by another master, gantry's reset brings it back by SDO, and the application's
//! SDO transfers (segmented, expedited, aborted, 64 KiB up and down by block) go beside
//! the moves, during which it frees nothing either (the buffer lent with a transfer goes
//! back to the application). The link is a lockstep one that does not allocate either (a
//! fixed queue in front of the nodes, which allocate nothing after they are built), so any
//! allocation counted is the cycle's.

use std::sync::{Arc, Mutex};

use gantry::canopen::CanopenBus;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::clock::StepClock;
use gantry::runtime::controller::{CommandHandle, Controller};
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::Engine;
use gantry::runtime::sdo::{SdoData, SdoError, SdoRequest, SDO_MAX_BYTES};
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::NodeId;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::canopen::dictionary::recorder_byte;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_tests::can_rig::{
    can_config_axes, can_config_with, servos, servos_with_pdos, Nodes, NodesLink,
};
use gantry_tests::homing::AXIS_SWITCHES_TOML;

mod counting {
    include!("../../kernel/tests/common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

/// An engine on simulated nodes behind the lockstep queue.
struct Watched<F: FnMut(u64)> {
    engine: Engine<CanopenBus>,
    ctl: Controller,
    /// The queue and the nodes.
    shared: Arc<Mutex<Nodes>>,
    /// Moves the queue's time one 2 ms cycle per cycle.
    clock: StepClock<F>,
    /// Cycles run under the counting allocator's watch.
    watched: u64,
}

impl<F: FnMut(u64)> Watched<F> {
    /// Up to `n` watched cycles, until `h` is final (its status).
    fn run(&mut self, h: Option<&CommandHandle>, n: usize) -> Option<CommandStatus> {
        for _ in 0..n {
            counting::watch(true);
            let running = self.engine.cycle(&mut self.clock);
            counting::watch(false);
            assert!(running);
            self.watched += 1;
            if let Some(s) = h.and_then(|h| self.engine.command_status(h.id())) {
                if s.is_final() {
                    return Some(s);
                }
            }
        }
        None
    }
}

/// The engine of `config` on `nodes` behind the lockstep queue (brought up while the
/// link's waits move the time), the controller, the queue and the step clock that moves
/// it from then on.
fn engine_on(
    config: &gantry::config::Config,
    nodes: Vec<gantry_sim::canopen::CanNode>,
) -> Watched<impl FnMut(u64)> {
    let shared = Arc::new(Mutex::new(Nodes::new(nodes)));
    let bus = CanopenBus::bring_up_on(
        config,
        Box::new(NodesLink(shared.clone())),
        &mut std::io::sink(),
    )
    .unwrap_or_else(|e| panic!("{}", gantry::error_chain::Chain(&e)));
    let cycle = Cycle::from_config(config, &bus).unwrap();
    let (engine, ends) = Engine::new(bus, cycle, config.rt.overrun_limit, 1024);
    let ctl = Controller::new(ends, config.axes.iter().map(|a| a.name.clone()).collect());
    let start = {
        let mut s = shared.lock().unwrap();
        s.stepped = true;
        s.clock_ns
    };
    let stepped = shared.clone();
    let clock = StepClock::new(2_000_000, start, move |to| stepped.lock().unwrap().tick(to));
    Watched {
        engine,
        ctl,
        shared,
        clock,
        watched: 0,
    }
}

#[test]
fn the_canopen_cycle_does_not_allocate() {
    let ids = [1u8, 2, 3, 4];
    // With a SYNC counter and gantry's heartbeat: their paths run in the watched cycles.
    let config = can_config_with(&ids, 2000, "csp", "sync_counter = 8");
    // Node 1 carries the recorder 0x2F00 and the scratch 0x2F01 of 64 KiB each: a
    // block transfer of the most a transfer carries goes each way in the watched cycles.
    let mut nodes = servos(&ids[1..]);
    let big = CanNodeConfig {
        recorder_bytes: SDO_MAX_BYTES,
        scratch_bytes: SDO_MAX_BYTES,
        ..CanNodeConfig::servo(NodeId::new(1).unwrap())
    };
    nodes.insert(0, CanNode::new(big).unwrap());
    let Watched {
        mut engine,
        ctl,
        shared,
        mut clock,
        ..
    } = engine_on(&config, nodes);
    let mut watched = 0u64;
    let mut cycle = |engine: &mut Engine<CanopenBus>, n: usize| {
        for _ in 0..n {
            counting::watch(true);
            let running = engine.cycle(&mut clock);
            counting::watch(false);
            assert!(running);
            watched += 1;
        }
    };
    let until_final = |engine: &mut Engine<CanopenBus>,
                       cycle: &mut dyn FnMut(&mut Engine<CanopenBus>, usize),
                       h: &CommandHandle| {
        for _ in 0..10_000 {
            cycle(engine, 1);
            if let Some(s) = engine
                .command_status(h.id())
                .filter(CommandStatus::is_final)
            {
                return s;
            }
        }
        panic!("not final");
    };
    // The counter counts.
    counting::watch(true);
    std::hint::black_box(vec![1u8; 16]);
    counting::watch(false);
    assert_eq!(counting::take_count(), 1, "the counting allocator works");
    assert_eq!(counting::take_frees(), 1, "and counts the vector's free");
    for axis in 0..4 {
        let h = ctl
            .command(axis, Command::Power(PowerCommand::Enable))
            .unwrap();
        assert_eq!(
            until_final(&mut engine, &mut cycle, &h),
            CommandStatus::Done
        );
        let home = Command::SetPosition {
            position: 0.0,
            relative: false,
        };
        let h = ctl.command(axis, home).unwrap();
        assert_eq!(
            until_final(&mut engine, &mut cycle, &h),
            CommandStatus::Done
        );
    }
    let moves = |to: f64| -> Vec<CommandHandle> {
        (0..4)
            .map(|a| {
                let m = MovePtp::new(PositioningMode::AbsNormal, to);
                ctl.command(a, Command::MovePtp(m)).unwrap()
            })
            .collect()
    };
    for h in moves(50.0) {
        assert_eq!(
            until_final(&mut engine, &mut cycle, &h),
            CommandStatus::Done
        );
    }
    // Node 2's heartbeat stays away: its axis stops with the reason.
    shared.lock().unwrap().drop = Some(0x702);
    let hs = moves(0.0);
    cycle(&mut engine, 250);
    assert!(engine.bus.fault(1).is_some(), "heartbeat fault");
    assert_eq!(
        engine.cycle.kernel.axis_status(1).unwrap().state,
        AxisState::ErrorStop
    );
    shared.lock().unwrap().drop = None;
    for (a, h) in hs.iter().enumerate() {
        if a != 1 {
            assert_eq!(until_final(&mut engine, &mut cycle, h), CommandStatus::Done);
        }
    }
    // Node 4 reset by another master (boot-up): its axis stops too.
    let reset = NmtFrame {
        command: NmtCommand::ResetNode,
        target: NmtTarget::Node(NodeId::new(4).unwrap()),
    };
    shared.lock().unwrap().deliver(&reset.emit());
    cycle(&mut engine, 5);
    assert!(engine.bus.fault(3).is_some(), "boot-up fault");
    // Resets bring both back: NMT reset communication and the SDO writes, inside the
    // watched cycles.
    for axis in [1, 3] {
        let h = ctl.reset(axis).unwrap();
        assert_eq!(
            until_final(&mut engine, &mut cycle, &h),
            CommandStatus::Done
        );
        let h = ctl
            .command(axis, Command::Power(PowerCommand::Enable))
            .unwrap();
        assert_eq!(
            until_final(&mut engine, &mut cycle, &h),
            CommandStatus::Done
        );
    }
    assert!(!engine.bus.any_fault());
    // SDO transfers beside the PDOs while the axes move, inside the watched cycles: a
    // segmented upload, an expedited download, an abort, 64 KiB up and down by block.
    let hs = moves(25.0);
    let window = SdoData::new(&50_000u32.to_le_bytes());
    let written: Vec<u8> = (0..SDO_MAX_BYTES).map(|i| recorder_byte(i + 1)).collect();
    let transfers = [
        SdoRequest::upload(0, 0x1008, 0),
        SdoRequest::download(2, 0x6065, 0, window),
        SdoRequest::upload(3, 0x2FFF, 0),
        SdoRequest::upload(0, 0x2F00, 0),
        SdoRequest::download(0, 0x2F01, 0, SdoData::new(&written)),
    ];
    let mut outcomes = Vec::with_capacity(transfers.len());
    let mut in_flight = 0;
    for request in transfers {
        let h = ctl.sdo(request).unwrap();
        let outcome = (0..20_000).find_map(|_| {
            cycle(&mut engine, 1);
            in_flight += 1;
            h.outcome()
        });
        outcomes.push(outcome.expect("the transfer ended"));
    }
    assert_eq!(
        outcomes[0].as_ref().map(SdoData::as_slice),
        Ok(&b"gantry-sim CiA 402 servo"[..])
    );
    assert_eq!(outcomes[1], Ok(SdoData::EMPTY));
    assert!(
        matches!(outcomes[2], Err(SdoError::Aborted { code, .. }) if code.0 == 0x0602_0000),
        "{:?}",
        outcomes[2]
    );
    let recorder: Vec<u8> = (0..SDO_MAX_BYTES).map(recorder_byte).collect();
    assert_eq!(
        outcomes[3].as_ref().map(SdoData::as_slice),
        Ok(&recorder[..]),
        "the 64 KiB upload"
    );
    assert_eq!(outcomes[4], Ok(SdoData::EMPTY));
    assert_eq!(
        shared.lock().unwrap().nodes[0].dictionary().scratch(),
        &written[..],
        "the 64 KiB download"
    );
    // Nor does the cycle free anything, before or while they run: the buffer lent with
    // each goes back to the application.
    let frees = counting::take_frees();
    eprintln!("{frees} frees in the watched cycles so far, {in_flight} with a transfer in flight");
    assert_eq!(frees, 0);
    for h in hs {
        assert_eq!(
            until_final(&mut engine, &mut cycle, &h),
            CommandStatus::Done
        );
    }
    let allocations = counting::take_count();
    assert_eq!(shared.lock().unwrap().overflow, 0);
    eprintln!("{allocations} allocations in {watched} watched cycles");
    assert!(watched > 500, "{watched} cycles");
    assert_eq!(allocations, 0);
}

/// The same with an I/O module (CiA 401, node 9) whose input is the axis' reference
/// switch: its TPDO read and routed every cycle, its heartbeat lost until the axis stops
/// ("switch module: ..."), and the reset that brings the module back (NMT reset
/// communication, its SDO configuration, NMT start) — all inside the watched cycles.
#[test]
fn the_canopen_cycle_with_a_switch_module_does_not_allocate() {
    use gantry_sim::plant::switches::SwitchCam;
    let config = gantry::config::Config::parse(
        "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\ncycle_us = 2000\n\
         [[axis]]\nname = \"a0\"\nnode = 1\npdo = \"csp-minimal\"\n\
         scaling = { counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }\n\
         max = { speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }\n\
         [axis.switches]\nreference = { from = \"module\", node = 9, input = 0 }\n",
        "can.toml",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut nodes = servos(&[1]);
    let cam = SwitchCam {
        input: 0,
        from: 100_000_000,
        to: 100_100_000,
        normally_closed: false,
    };
    let module = CanNodeConfig::switches(NodeId::new(9).unwrap(), NodeId::new(1).unwrap(), &[cam])
        .expect("cams");
    nodes.push(CanNode::new(module).expect("module"));
    let mut w = engine_on(&config, nodes);
    assert_eq!(w.engine.bus.drives(), 2, "the drive and the module");
    for command in [
        Command::Power(PowerCommand::Enable),
        Command::SetPosition {
            position: 0.0,
            relative: false,
        },
        Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 20.0)),
    ] {
        let h = w.ctl.command(0, command).unwrap();
        assert_eq!(w.run(Some(&h), 10_000), Some(CommandStatus::Done));
    }
    // The module's heartbeat stays away: the axis stops, naming the module.
    w.shared.lock().unwrap().drop = Some(0x709);
    let h = w
        .ctl
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 0.0)),
        )
        .unwrap();
    w.run(None, 250);
    let why = w
        .engine
        .bus
        .fault(0)
        .map(|f| f.to_string())
        .unwrap_or_default();
    assert!(why.starts_with("switch module: CANopen node 9"), "{why}");
    assert_eq!(
        w.engine.cycle.kernel.axis_status(0).unwrap().state,
        AxisState::ErrorStop
    );
    assert!(w
        .engine
        .command_status(h.id())
        .is_some_and(|s| s.is_final()));
    w.shared.lock().unwrap().drop = None;
    // The reset brings the module back by SDO inside the watched cycles.
    let h = w.ctl.reset(0).unwrap();
    assert_eq!(w.run(Some(&h), 10_000), Some(CommandStatus::Done));
    assert!(!w.engine.bus.any_fault());
    // The drive stayed enabled through it or the reset left it disabled (it stopped by
    // its own 0x6007 reaction): enabled either way, the axis moves again.
    if w.engine.cycle.kernel.axis_status(0).unwrap().state == AxisState::Disabled {
        let e = w
            .ctl
            .command(0, Command::Power(PowerCommand::Enable))
            .unwrap();
        assert_eq!(w.run(Some(&e), 10_000), Some(CommandStatus::Done));
    }
    let h = w
        .ctl
        .command(
            0,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 0.0)),
        )
        .unwrap();
    assert_eq!(w.run(Some(&h), 10_000), Some(CommandStatus::Done));
    let allocations = counting::take_count();
    assert_eq!(w.shared.lock().unwrap().overflow, 0);
    eprintln!("{allocations} allocations in {} watched cycles", w.watched);
    assert!(w.watched > 500, "{} cycles", w.watched);
    assert_eq!(allocations, 0);
}

/// The same with two drives whose process data take seven PDOs each (the full CSP
/// layout with switches and both touch probes: 2 RPDOs, 5 TPDOs, TPDO5 on a COB-ID
/// gantry lent): their TPDOs routed by COB-ID every cycle, a heartbeat lost until the
/// axis stops, and the reset that maps all seven again by SDO — inside the watched
/// cycles.
#[test]
fn the_canopen_cycle_with_five_tpdos_a_drive_does_not_allocate() {
    let ids = [1u8, 2];
    let config = can_config_axes(&ids, 2000, "csp", "", AXIS_SWITCHES_TOML);
    let mut w = engine_on(&config, servos_with_pdos(&ids, 8));
    for d in 0..2 {
        let plan = w.engine.bus.plan(d).unwrap();
        assert_eq!((plan.rpdos.len(), plan.tpdos.len()), (2, 5));
    }
    let to = |mm: f64| {
        Some(Command::MovePtp(MovePtp::new(
            PositioningMode::AbsNormal,
            mm,
        )))
    };
    let enable = || Some(Command::Power(PowerCommand::Enable));
    let here = || {
        Some(Command::SetPosition {
            position: 0.0,
            relative: false,
        })
    };
    // Each (axis, command) to its end; None: gantry's reset.
    let steps = |w: &mut Watched<_>, steps: Vec<(usize, Option<Command>)>| {
        for (axis, command) in steps {
            let h = match command {
                Some(c) => w.ctl.command(axis, c).unwrap(),
                None => w.ctl.reset(axis).unwrap(),
            };
            assert_eq!(
                w.run(Some(&h), 10_000),
                Some(CommandStatus::Done),
                "axis {axis}: {:?}",
                w.engine.bus.fault(axis).map(|f| f.to_string())
            );
        }
    };
    steps(
        &mut w,
        vec![
            (0, enable()),
            (1, enable()),
            (0, here()),
            (1, here()),
            (0, to(20.0)),
            (1, to(20.0)),
        ],
    );
    // Node 2's heartbeat stays away: its axis stops.
    w.shared.lock().unwrap().drop = Some(0x702);
    w.run(None, 250);
    assert!(w.engine.bus.fault(1).is_some(), "heartbeat fault");
    w.shared.lock().unwrap().drop = None;
    let mut again = vec![(1, None)];
    if w.engine.cycle.kernel.axis_status(1).unwrap().state == AxisState::ErrorStop {
        // The reset leaves the drive disabled (its own 0x6007 reaction stopped it).
        again.push((1, enable()));
    }
    again.extend([(0, to(-15.0)), (1, to(-15.0))]);
    steps(&mut w, again);
    assert!(!w.engine.bus.any_fault());
    let allocations = counting::take_count();
    assert_eq!(w.shared.lock().unwrap().overflow, 0);
    eprintln!("{allocations} allocations in {} watched cycles", w.watched);
    assert!(w.watched > 500, "{} cycles", w.watched);
    assert_eq!(allocations, 0);
}
