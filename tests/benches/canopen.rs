//! The CANopen master's CPU per cycle with 8 CiA-402 drives (issue 12 §7: target ≤ 20 µs),
//! in one thread: the engine's whole cycle — decode 8 drives' TPDOs into their inputs,
//! kernel step, encode, 8 RPDOs and the SYNC sent, 16 TPDOs received and routed, the
//! heartbeat and fault checks — on a link that answers each SYNC at once with the TPDOs
//! of perfect drives (statusword from the controlword, position = target), so that the
//! line is the master's alone. The bus was brought up on simulated nodes before (SDO
//! mapping: 8 drives × 1 RPDO + 2 TPDOs of the full CSP layout, at 4 ms they fit 1 Mbit/s).
//! The simulated nodes' clock is not run while the mirror answers. Also timed, in the same
//! run: the mirror alone on one cycle's frames (its share of the master line, to
//! subtract), the kernel step alone for the 8 moving axes (the baseline, as the EtherCAT
//! bench's), and the same cycle on the simulated nodes (master + 8 simulated drives).
//!
//! Measured (2026-11-25, this 2-core shared VM under other builds, release, medians, two
//! runs): master cycle 4.46 / 4.33 µs, mirror alone 0.58 / 0.56 µs, so ≈ 3.8–3.9 µs of
//! master CPU per cycle (target ≤ 20 µs); kernel step alone 0.70 / 0.45 µs (the master's
//! cycle ≈ 5.6–8.4× its kernel step); master + 8 simulated nodes 36 / 30 µs.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex};

use gantry::canopen::pdo::DrivePlan;
use gantry::canopen::{CanLink, CanopenBus, Received};
use gantry::runtime::bus::CycleBus;
use gantry::runtime::clock::StepClock;
use gantry::runtime::controller::Controller;
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::Engine;
use gantry_drives::canopen::cob_id::CobId;
use gantry_drives::canopen::CanFrame;
use gantry_kernel::axis::command::{Command, MoveDirection, MoveVelocity, PowerCommand};
use gantry_tests::can_rig::{can_config, servos, Nodes, NodesLink};

const DRIVES: u8 = 8;

/// Perfect drives: each RPDO's controlword and target kept, each SYNC answered with the
/// TPDOs.
struct Mirror {
    on: bool,
    plans: Vec<(u8, DrivePlan)>,
    /// Per drive: controlword, target.
    state: Vec<(u16, i32)>,
    queue: VecDeque<CanFrame>,
    syncs: u64,
}

fn statusword(cw: u16) -> u16 {
    match cw & 0x8F {
        0x0F => 0x0637,
        0x07 => 0x0633,
        0x06 => 0x0631,
        _ => 0x0650,
    }
}

impl Mirror {
    fn on_frame(&mut self, f: &CanFrame) {
        match CobId::classify(f.id()) {
            Ok(CobId::Rpdo(n, node)) => {
                let Some(i) = self.plans.iter().position(|(id, _)| *id == node.get()) else {
                    return;
                };
                let plan = &self.plans[i].1;
                let Some(p) = plan.rpdos.iter().find(|p| p.number == n) else {
                    return;
                };
                for m in &p.entries {
                    let b = &f.data()[m.in_pdo..m.in_pdo + m.size()];
                    match m.object.index {
                        0x6040 => self.state[i].0 = u16::from_le_bytes([b[0], b[1]]),
                        0x607A => self.state[i].1 = i32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                        _ => {}
                    }
                }
            }
            Ok(CobId::Sync) => {
                // Heartbeats every 100 ms (25 cycles of 4 ms): Operational.
                self.syncs += 1;
                if self.syncs % 25 == 0 {
                    for (node, _) in &self.plans {
                        let id = 0x700 + u32::from(*node);
                        self.queue.push_back(CanFrame::new(id, &[0x05]).unwrap());
                    }
                }
                for (i, (node, plan)) in self.plans.iter().enumerate() {
                    let (cw, target) = self.state[i];
                    for p in &plan.tpdos {
                        let mut data = [0u8; 8];
                        for m in &p.entries {
                            let at = m.in_pdo;
                            match m.object.index {
                                0x6041 => {
                                    data[at..at + 2].copy_from_slice(&statusword(cw).to_le_bytes())
                                }
                                0x6064 => data[at..at + 4].copy_from_slice(&target.to_le_bytes()),
                                0x6061 => data[at] = 8,
                                _ => {}
                            }
                        }
                        let id =
                            u32::from(0x180 + 0x100 * u16::from(p.number - 1) + u16::from(*node));
                        self.queue
                            .push_back(CanFrame::new(id, &data[..p.len]).unwrap());
                    }
                }
            }
            _ => {}
        }
    }
}

/// Simulated nodes until the mirror is on.
struct BenchLink {
    nodes: NodesLink,
    mirror: Arc<Mutex<Mirror>>,
}

impl CanLink for BenchLink {
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        let mut m = self.mirror.lock().unwrap();
        if m.on {
            m.on_frame(frame);
            Ok(())
        } else {
            drop(m);
            self.nodes.send(frame)
        }
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        let mut m = self.mirror.lock().unwrap();
        if m.on {
            return Ok(m
                .queue
                .pop_front()
                .map(|frame| Received { frame, at_ns: None }));
        }
        drop(m);
        self.nodes.receive(deadline_ns)
    }

    fn now_ns(&self) -> u64 {
        self.nodes.now_ns()
    }
}

type Clock = StepClock<Box<dyn FnMut(u64)>>;

fn engine(mirror: bool) -> (Engine<CanopenBus>, Controller, Clock) {
    let ids: Vec<u8> = (1..=DRIVES).collect();
    let config = can_config(&ids, 4000, "csp");
    let nodes = Arc::new(Mutex::new(Nodes::new(servos(&ids))));
    let m = Arc::new(Mutex::new(Mirror {
        on: false,
        plans: Vec::new(),
        state: vec![(0, 0); ids.len()],
        queue: VecDeque::with_capacity(256),
        syncs: 0,
    }));
    let link = BenchLink {
        nodes: NodesLink(nodes.clone()),
        mirror: m.clone(),
    };
    let bus = CanopenBus::bring_up_on(&config, Box::new(link), &mut io::sink()).unwrap();
    {
        let mut m = m.lock().unwrap();
        m.plans = (0..bus.drives())
            .map(|i| (bus.node(i).unwrap().get(), bus.plan(i).unwrap().clone()))
            .collect();
        m.on = mirror;
    }
    let cycle = Cycle::from_config(&config, &bus).unwrap();
    let (engine, ends) = Engine::new(bus, cycle, 10, 1024);
    let ctl = Controller::new(ends, ids.iter().map(|i| format!("a{i}")).collect());
    let start = {
        let mut n = nodes.lock().unwrap();
        n.stepped = true;
        n.clock_ns
    };
    // With the mirror on, the simulated nodes are idle: their clock is not run, so that
    // none of their work (timers, heartbeats) lands in the master's line.
    let clock: Clock = StepClock::new(
        4_000_000,
        start,
        Box::new(move |to| {
            if !mirror {
                nodes.lock().unwrap().tick(to)
            }
        }),
    );
    (engine, ctl, clock)
}

/// Every axis enabled and moving at constant speed.
fn moving(mirror: bool) -> (Engine<CanopenBus>, Controller, Clock) {
    let (mut e, ctl, mut clock) = engine(mirror);
    for a in 0..usize::from(DRIVES) {
        ctl.command(a, Command::Power(PowerCommand::Enable))
            .unwrap();
    }
    for _ in 0..50 {
        e.cycle(&mut clock);
    }
    for a in 0..usize::from(DRIVES) {
        let v = MoveVelocity::new(MoveDirection::Positive, 20.0);
        ctl.command(a, Command::MoveVelocity(v)).unwrap();
    }
    for _ in 0..200 {
        e.cycle(&mut clock);
    }
    assert!(!e.bus.any_fault(), "{:?}", e.bus.fault(0));
    assert_eq!(e.bus.counters().lost, 0);
    (e, ctl, clock)
}

/// The master's cycle, drives answering at once.
#[divan::bench]
fn master_cycle_8_drives(bencher: divan::Bencher) {
    let (mut e, _ctl, mut clock) = moving(true);
    bencher.bench_local(|| e.cycle(&mut clock));
}

/// The mirror's share of the master line: what the bench link does per cycle (8 RPDOs
/// and the SYNC taken, 16 TPDOs made and handed back), on the frames of one real cycle.
/// Subtracted from the master line, it leaves the master's own work.
#[divan::bench]
fn mirror_alone_8_drives(bencher: divan::Bencher) {
    let (e, _ctl, _clock) = moving(true);
    let plans: Vec<(u8, DrivePlan)> = (0..e.bus.drives())
        .map(|i| (e.bus.node(i).unwrap().get(), e.bus.plan(i).unwrap().clone()))
        .collect();
    let mut sent: Vec<CanFrame> = Vec::new();
    for (node, plan) in &plans {
        for p in &plan.rpdos {
            let id = u32::from(0x200 + 0x100 * u16::from(p.number - 1) + u16::from(*node));
            let mut data = [0u8; 8];
            data[..2].copy_from_slice(&0x000Fu16.to_le_bytes());
            sent.push(CanFrame::new(id, &data[..p.len]).unwrap());
        }
    }
    sent.push(CanFrame::new(0x080, &[]).unwrap());
    let mirror = Mutex::new(Mirror {
        on: true,
        plans,
        state: vec![(0, 0); usize::from(DRIVES)],
        queue: VecDeque::with_capacity(256),
        syncs: 0,
    });
    bencher.bench_local(|| {
        for f in &sent {
            mirror.lock().unwrap().on_frame(f);
        }
        let mut n = 0;
        while let Some(f) = mirror.lock().unwrap().queue.pop_front() {
            n += f.data().len();
        }
        // A receive that finds nothing ends each exchange, as in the cycle.
        let _ = mirror.lock().unwrap().queue.pop_front();
        n
    });
}

/// Baseline of the same run: the kernel step alone for the 8 moving axes (on the last
/// feedback), as the EtherCAT bench's baseline.
#[divan::bench]
fn kernel_step_8_axes(bencher: divan::Bencher) {
    let (mut e, _ctl, _clock) = moving(true);
    bencher.bench_local(|| e.cycle.step());
}

/// The same cycle on 8 simulated CiA 402 nodes (master + simulator).
#[divan::bench]
fn master_and_simulated_nodes_8_drives(bencher: divan::Bencher) {
    let (mut e, _ctl, mut clock) = moving(false);
    bencher.bench_local(|| e.cycle(&mut clock));
}

fn main() {
    divan::main();
}
