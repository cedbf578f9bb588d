//! The CANopen servo in cyclic synchronous position mode, in lockstep on the in-memory
//! bus at 1 Mbit/s: the test is the master (NMT, PDO mapping by SDO, RPDO then SYNC every
//! 1 ms, TPDOs back), takes the drive through the CiA 402 state machine and moves it;
//! EMCY on a fault and its reset; the heartbeat consumer (CiA 301 §7.2.8.3.2.3) and the
//! missed-setpoint limit fault the drive.

mod canopen_common;

use canopen_common::*;
use gantry_drives::canopen::emcy::Emergency;
use gantry_drives::canopen::nmt::NmtCommand;
use gantry_drives::canopen::sdo::AbortCode;
use gantry_drives::cia402::objects::{self, ObjectId};
use gantry_drives::cia402::pdo::mapping_entry;
use gantry_drives::cia402::State;
use gantry_sim::canopen::nmt::NmtSlaveState;
use gantry_sim::canopen::{CanBus, CanNode, CanNodeConfig};
use gantry_sim::plant::record::{max_step_counts, Expectation};

const INVALID: u32 = 1 << 31;
/// One revolution of the default servo.
const REV: i32 = 1 << 17;

struct Axis {
    node: u8,
    sw: u16,
    pos: i32,
}

struct Rig {
    m: Master,
    axes: Vec<Axis>,
    /// EMCYs received, in order.
    emcy: Vec<(u64, Emergency)>,
    /// The master's own heartbeat (node id, period), sent while `Some`.
    heartbeat: Option<(u8, u64)>,
    last_heartbeat: u64,
}

fn entry(o: ObjectId) -> [u8; 4] {
    mapping_entry(&o).to_le_bytes()
}

impl Rig {
    /// Nodes `ids` on a 1 Mbit/s bus, booted, PDOs mapped by SDO, operational.
    fn new(ids: &[u8]) -> Self {
        let configs: Vec<_> = ids.iter().map(|&n| CanNodeConfig::servo(id(n))).collect();
        Self::with_configs(&configs)
    }

    /// [`Rig::new`] with nodes of these configurations.
    fn with_configs(configs: &[CanNodeConfig]) -> Self {
        let ids: Vec<u8> = configs.iter().map(|c| c.node.get()).collect();
        let ids = &ids[..];
        let nodes = configs.iter().map(|c| CanNode::new(*c).unwrap()).collect();
        let mut m = Master::with_nodes(vec![]);
        m.bus = CanBus::new(nodes).with_bitrate(1_000_000);
        m.sync_overflow = 16;
        m.step(0);
        for &n in ids {
            // RPDO1: controlword + target position; TPDO1: statusword + position actual;
            // both synchronous every SYNC (mapped afresh, as a master does).
            let rpdo = 0x200 + u32::from(n);
            let tpdo = 0x180 + u32::from(n);
            for (comm, mapping, cob, objs) in [
                (
                    0x1400,
                    0x1600,
                    rpdo,
                    [objects::CONTROLWORD, objects::TARGET_POSITION],
                ),
                (
                    0x1800,
                    0x1A00,
                    tpdo,
                    [objects::STATUSWORD, objects::POSITION_ACTUAL_VALUE],
                ),
            ] {
                m.write(n, comm, 1, &(INVALID | cob).to_le_bytes()).unwrap();
                m.write(n, mapping, 0, &[0]).unwrap();
                for (s, o) in objs.iter().enumerate() {
                    m.write(n, mapping, s as u8 + 1, &entry(*o)).unwrap();
                }
                m.write(n, mapping, 0, &[2]).unwrap();
                m.write(n, comm, 2, &[1]).unwrap();
                m.write(n, comm, 1, &cob.to_le_bytes()).unwrap();
            }
            assert_eq!(m.read(n, 0x6060, 0).unwrap(), [8], "CSP");
            // SYNCs carry a counter up to 16 (0x1019, CiA 301 §7.5.2.22).
            m.write(n, 0x1019, 0, &[16]).unwrap();
        }
        m.nmt(NmtCommand::Start, None);
        m.take_inbox();
        // The configuration's frames took bus time the 0.1 ms SDO rounds did not count.
        m.now = m.now.max(m.bus.now_ns());
        let axes = ids
            .iter()
            .map(|&node| Axis {
                node,
                sw: 0,
                pos: 0,
            })
            .collect();
        Self {
            m,
            axes,
            emcy: Vec::new(),
            heartbeat: None,
            last_heartbeat: 0,
        }
    }

    /// One 1 ms cycle: RPDOs (`command` per axis, None: not sent), then SYNC; reads the
    /// TPDOs and EMCYs that come back.
    fn cycle(&mut self, command: &[Option<(u16, i32)>]) {
        self.m.step(MS);
        if let Some((hb_node, period)) = self.heartbeat {
            if self.m.now >= self.last_heartbeat + period {
                self.m.bus.send(frame(0x700 + u16::from(hb_node), &[0x05]));
                self.last_heartbeat = self.m.now;
            }
        }
        for (a, c) in self.axes.iter().zip(command) {
            if let Some((cw, target)) = c {
                let mut d = [0u8; 6];
                d[..2].copy_from_slice(&cw.to_le_bytes());
                d[2..].copy_from_slice(&target.to_le_bytes());
                self.m.bus.send(frame(0x200 + u16::from(a.node), &d));
            }
        }
        let sync = self.m.sync_frame();
        self.m.send(&[sync]);
        self.read_inbox();
    }

    /// Lets time pass without a cycle (the master silent).
    fn idle(&mut self, dt: u64) {
        self.m.step(dt);
        self.read_inbox();
    }

    /// When the last frame with COB-ID `id` was put on the bus (ns).
    fn last_frame_at(&self, id: u16) -> u64 {
        let frame = self.m.bus.log().iter().rev().find(|d| d.frame.id() == id);
        frame
            .unwrap_or_else(|| panic!("no frame 0x{id:03X} on the bus"))
            .at_ns
    }

    fn read_inbox(&mut self) {
        for d in self.m.take_inbox() {
            for a in &mut self.axes {
                if d.frame.id() == 0x180 + u16::from(a.node) {
                    let b = d.frame.data();
                    a.sw = u16::from_le_bytes([b[0], b[1]]);
                    a.pos = i32::from_le_bytes([b[2], b[3], b[4], b[5]]);
                }
            }
            if let Ok(e) = Emergency::parse(&d.frame) {
                self.emcy.push((d.at_ns, e));
            }
        }
    }

    /// Every axis through Shutdown, Switch on, Enable operation (CiA 402 transitions 2,
    /// 3, 4), holding its position; returns the cycles it took.
    fn enable(&mut self) -> usize {
        for k in 0..100 {
            let cmd: Vec<_> = self
                .axes
                .iter()
                .map(|a| {
                    let cw = match a.sw & 0x6F {
                        0x21 => 0x07,        // Ready to switch on → Switch on
                        0x23 | 0x27 => 0x0F, // Switched on → Enable operation
                        _ => 0x06,           // Switch on disabled → Shutdown
                    };
                    Some((cw, a.pos))
                })
                .collect();
            if self.axes.iter().all(|a| a.sw & 0x6F == 0x27) {
                return k;
            }
            self.cycle(&cmd);
        }
        panic!(
            "not enabled: {:?}",
            self.axes.iter().map(|a| a.sw).collect::<Vec<_>>()
        );
    }

    fn servo(&self, i: usize) -> &gantry_sim::plant::servo::ServoDrive {
        self.m.node(i).servo().expect("a servo node")
    }
}

/// Cosine position profile from `from` by `dist` over `n` cycles, at cycle `k`.
fn profile(from: i32, dist: i32, n: usize, k: usize) -> i32 {
    let s = (k.min(n) as f64 / n as f64 * std::f64::consts::PI).cos();
    from + (f64::from(dist) * (1.0 - s) / 2.0).round() as i32
}

#[test]
fn csp_move_of_three_drives_in_lockstep_at_1_mbit() {
    let ids = [1u8, 2, 3];
    let mut r = Rig::new(&ids);
    let took = r.enable();
    assert!(took <= 6, "enabled in {took} cycles");
    for (i, a) in r.axes.iter().enumerate() {
        assert_eq!(
            r.servo(i).state(),
            State::OperationEnabled,
            "node {}",
            a.node
        );
    }
    // Each axis moves a different distance, 500 ms, then holds 200 ms.
    let starts: Vec<i32> = r.axes.iter().map(|a| a.pos).collect();
    let dists = [REV, -REV, 2 * REV];
    let n = 500;
    let mut worst_lag = 0i64;
    let mut busiest = 0u64;
    for k in 1..=n + 200 {
        let cmd: Vec<_> = (0..ids.len())
            .map(|i| Some((0x0F, profile(starts[i], dists[i], n, k))))
            .collect();
        r.cycle(&cmd);
        busiest = busiest.max(r.m.bus.now_ns() - r.m.now);
        for (i, a) in r.axes.iter().enumerate() {
            // The TPDO of this SYNC carries the position sampled at it; the demand it
            // followed is the target of the previous cycle.
            let lag = i64::from(profile(starts[i], dists[i], n, k - 1)) - i64::from(a.pos);
            worst_lag = worst_lag.max(lag.abs());
            assert_eq!(a.sw & 0x6F, 0x27, "node {} left Operation enabled", a.node);
        }
    }
    // Peak speed: π/2 · 2 rev / 0.5 s ≈ 6.3 rev/s; measured worst lag 158 counts
    // (0.12 % of a turn) behind the demand of the previous SYNC.
    assert!(worst_lag < 300, "worst lag {worst_lag} counts");
    let vmax = std::f64::consts::FRAC_PI_2 * f64::from(2 * REV) / 0.5;
    for (i, a) in r.axes.iter().enumerate() {
        let end = starts[i] + dists[i];
        assert!(
            (a.pos - end).abs() <= 2,
            "node {}: at {} for {end}",
            a.node,
            a.pos
        );
        assert!((r.servo(i).position() - f64::from(end)).abs() < 2.0);
        let rec = r.servo(i).record();
        rec.check(&Expectation {
            max_step_counts: max_step_counts(vmax, 1e-3),
            injects_following_error: false,
            phase_locked: true,
        })
        .unwrap();
        assert_eq!((rec.sync_missed, rec.sync_doubled), (0, 0));
        assert_eq!(rec.faults, 0);
        assert!(rec.targets >= 700, "{} targets", rec.targets);
        assert_eq!(r.m.node(i).counters().missed_in_row, 0);
    }
    assert!(r.emcy.is_empty(), "{:?}", r.emcy);
    assert_eq!(
        r.m.node(0).counters().last_sync_counter.map(|c| c <= 16),
        Some(true)
    );
    // 3 RPDOs of 6 bytes (115 bits each, stuffing counted) + SYNC with counter (65) + 3
    // TPDOs (115) + the 3 heartbeats (65 each) in the cycles they fall into: 950 µs of
    // the 1 ms cycle at 1 Mbit/s, the busiest cycle still ending within it. (Four such
    // drives need 985 µs without heartbeats, 1245 µs with: they do not fit.)
    assert_eq!(
        busiest, 950_000,
        "bus busy {busiest} ns in the busiest cycle"
    );
}

#[test]
fn emcy_on_a_drive_fault_and_the_reset_emcy_when_it_clears() {
    let mut r = Rig::new(&[5]);
    r.enable();
    let p = r.axes[0].pos;
    for _ in 0..5 {
        r.cycle(&[Some((0x0F, p))]);
    }
    assert!(r.emcy.is_empty());
    // A target half a turn away, from standstill: the loops cannot follow and the
    // following error (beyond 0x6065 for 0x6066 = 10 ms) faults the drive with 0x8611.
    r.cycle(&[Some((0x0F, p + REV / 2))]);
    for _ in 0..100 {
        r.cycle(&[Some((0x0F, p + REV / 2))]);
    }
    assert_eq!(r.servo(0).state(), State::Fault);
    assert_eq!(r.emcy.len(), 1, "{:?}", r.emcy);
    let e = r.emcy[0].1;
    assert_eq!(e.error_code, 0x8611);
    assert_eq!(e.error_register, 0x21, "generic + device profile");
    assert_eq!(r.axes[0].sw & 0x4F, 0x08, "TPDO shows Fault");
    assert_eq!(r.m.read(5, 0x1001, 0).unwrap(), [0x21]);
    assert_eq!(r.m.read(5, 0x603F, 0).unwrap(), 0x8611u16.to_le_bytes());
    // 0x1003 keeps it: one error, sub 1 its code; sub 2 holds none.
    assert_eq!(r.m.read(5, 0x1003, 0).unwrap(), [1]);
    assert_eq!(r.m.read(5, 0x1003, 1).unwrap(), 0x8611u32.to_le_bytes());
    assert_eq!(r.m.read(5, 0x1003, 2), Err(AbortCode::NO_DATA));
    assert_eq!(r.m.write(5, 0x1003, 0, &[1]), Err(AbortCode::INVALID_VALUE));
    assert_eq!(r.m.write(5, 0x1003, 1, &[0; 4]), Err(AbortCode::READ_ONLY));
    // Fault reset (rising edge of bit 7): the error reset EMCY, error register 0.
    let pos = r.axes[0].pos;
    r.cycle(&[Some((0x00, pos))]);
    r.cycle(&[Some((0x80, pos))]);
    r.cycle(&[Some((0x00, pos))]);
    assert_eq!(r.servo(0).state(), State::SwitchOnDisabled);
    assert_eq!(r.emcy.len(), 2, "{:?}", r.emcy);
    let e = r.emcy[1].1;
    assert!(e.is_reset());
    assert_eq!(e.error_register, 0);
    assert_eq!(r.m.read(5, 0x1001, 0).unwrap(), [0]);
    // The history outlives the fault until the master clears it.
    assert_eq!(r.m.read(5, 0x1003, 0).unwrap(), [1]);
    r.m.write(5, 0x1003, 0, &[0]).unwrap();
    assert_eq!(r.m.read(5, 0x1003, 0).unwrap(), [0]);
    assert_eq!(r.m.read(5, 0x1003, 1), Err(AbortCode::NO_DATA));
}

#[test]
fn heartbeat_consumer_timeout_faults_the_drive() {
    let mut r = Rig::new(&[6]);
    // Node 6 watches the master (node id 1) with 50 ms; the master beats every 20 ms.
    r.m.write(6, 0x1016, 1, &(1u32 << 16 | 50).to_le_bytes())
        .unwrap();
    // Monitoring starts with the first heartbeat: 200 ms without any is no fault.
    r.enable();
    let p = r.axes[0].pos;
    for _ in 0..200 {
        r.cycle(&[Some((0x0F, p))]);
    }
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
    r.heartbeat = Some((1, 20 * MS));
    r.last_heartbeat = 0;
    for _ in 0..300 {
        r.cycle(&[Some((0x0F, p))]);
    }
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
    assert!(r.emcy.is_empty());
    // The master falls silent: no heartbeat, no PDO, no SYNC.
    let last = r.last_heartbeat;
    r.heartbeat = None;
    while r.emcy.is_empty() && r.m.now < last + 200 * MS {
        r.idle(MS);
    }
    let (at, e) = r.emcy[0];
    assert_eq!(e.error_code, 0x8130);
    r.idle(10 * MS);
    assert_eq!(r.emcy.len(), 1, "one EMCY for the one event: {:?}", r.emcy);
    // The node saw the master's last heartbeat when its frame ended; it notices the
    // timeout at its first tick 50 ms after (ticks are 1 ms apart here) and the EMCY
    // takes its 135 µs on the bus.
    let seen = r.last_frame_at(0x701);
    assert!(seen >= last);
    assert!(
        at > seen + 50 * MS && at <= seen + 51 * MS + 135_000,
        "EMCY {} ns after the last heartbeat",
        at - seen
    );
    // CiA 402 0x6007 = 1: fault (its reaction brakes, then Fault); 0x1029:01 = 0: the node
    // left Operational for Pre-operational.
    assert!(matches!(
        r.servo(0).state(),
        State::Fault | State::FaultReactionActive
    ));
    assert_eq!(r.servo(0).error_code(), 0x8130);
    assert_eq!(r.m.node(0).nmt_state(), NmtSlaveState::PreOperational);
    r.idle(100 * MS);
    assert_eq!(r.servo(0).state(), State::Fault);
    assert_eq!(r.m.read(6, 0x603F, 0).unwrap(), 0x8130u16.to_le_bytes());
    assert_eq!(r.m.read(6, 0x1001, 0).unwrap(), [0x11]);
}

#[test]
fn missed_rpdos_count_and_fault_at_the_limit_with_8250() {
    let mut r = Rig::new(&[7]);
    assert_eq!(r.m.read(7, 0x2010, 0).unwrap(), 4u16.to_le_bytes());
    r.enable();
    let p = r.axes[0].pos;
    r.cycle(&[Some((0x0F, p))]);
    // Three SYNCs without the RPDO: counted, no fault; the next RPDO resets the count.
    for _ in 0..3 {
        r.cycle(&[None]);
    }
    assert_eq!(r.m.node(0).counters().missed_in_row, 3);
    assert_eq!(r.servo(0).record().sync_missed, 3);
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
    r.cycle(&[Some((0x0F, p))]);
    assert_eq!(r.m.node(0).counters().missed_in_row, 0);
    // Four in a row: fault 0x8250 (RPDO timeout) and its EMCY.
    for _ in 0..4 {
        r.cycle(&[None]);
    }
    assert!(matches!(
        r.servo(0).state(),
        State::Fault | State::FaultReactionActive
    ));
    assert_eq!(r.servo(0).record().sync_missed, 7);
    assert_eq!(r.emcy.len(), 1);
    assert_eq!(r.emcy[0].1.error_code, 0x8250);
    assert_eq!(r.emcy[0].1.error_register, 0x11);
    // 0 switches the monitor off.
    let mut r = Rig::new(&[7]);
    r.m.write(7, 0x2010, 0, &0u16.to_le_bytes()).unwrap();
    r.enable();
    for _ in 0..20 {
        r.cycle(&[None]);
    }
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
    assert_eq!(r.servo(0).record().sync_missed, 20);
}

#[test]
fn sync_watchdog_0x1006_faults_the_drive_when_sync_stays_away() {
    let mut r = Rig::new(&[8]);
    // 1 ms cycle: the watchdog fires 1.5 ms after the last SYNC.
    r.m.write(8, 0x1006, 0, &1000u32.to_le_bytes()).unwrap();
    assert_eq!(r.m.read(8, 0x1006, 0).unwrap(), 1000u32.to_le_bytes());
    r.enable();
    let p = r.axes[0].pos;
    for _ in 0..100 {
        r.cycle(&[Some((0x0F, p))]);
    }
    assert!(r.emcy.is_empty(), "{:?}", r.emcy);
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
    // SYNC stops (heartbeats go on: no heartbeat consumer here).
    let last = r.m.now;
    for _ in 0..20 {
        r.idle(100_000);
    }
    assert_eq!(r.emcy.len(), 1, "{:?}", r.emcy);
    let (at, e) = r.emcy[0];
    assert_eq!(e.error_code, 0x8100);
    // The node saw the last SYNC when its frame ended; 1.5 ms after, at the next 0.1 ms
    // tick, it sends the EMCY (135 µs on the bus).
    let sync = r.last_frame_at(0x080);
    assert!(sync >= last);
    assert!(
        at > sync + 1_500_000 && at <= sync + 1_600_000 + 135_000,
        "EMCY {} ns after the last SYNC",
        at - sync
    );
    assert!(matches!(
        r.servo(0).state(),
        State::Fault | State::FaultReactionActive
    ));
    assert_eq!(r.servo(0).error_code(), 0x8100);
    // Off (0): no watchdog.
    let mut r = Rig::new(&[8]);
    r.enable();
    for _ in 0..50 {
        r.idle(MS);
    }
    assert!(r.emcy.is_empty());
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
}

#[test]
fn the_sync_watchdog_margin_is_the_nodes_setting_and_at_least_one_period() {
    // 10 periods of 1 ms: silence of 5 ms is tolerated, more than 10 ms is not.
    let config = CanNodeConfig {
        sync_timeout_periods: 10.0,
        ..CanNodeConfig::servo(id(8))
    };
    let mut r = Rig::with_configs(&[config]);
    r.m.write(8, 0x1006, 0, &1000u32.to_le_bytes()).unwrap();
    r.enable();
    let p = r.axes[0].pos;
    for _ in 0..20 {
        r.cycle(&[Some((0x0F, p))]);
    }
    for _ in 0..50 {
        r.idle(100_000);
    }
    assert!(r.emcy.is_empty(), "5 ms without SYNC: {:?}", r.emcy);
    for _ in 0..20 {
        r.cycle(&[Some((0x0F, p))]);
    }
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
    for _ in 0..120 {
        r.idle(100_000);
    }
    assert_eq!(r.emcy.len(), 1, "{:?}", r.emcy);
    let (at, e) = r.emcy[0];
    assert_eq!(e.error_code, 0x8100);
    let sync = r.last_frame_at(0x080);
    assert!(
        at > sync + 10_000_000 && at <= sync + 10_100_000 + 135_000,
        "EMCY {} ns after the last SYNC",
        at - sync
    );
    // Below one period, or not a number: refused, naming the node and the key.
    for bad in [0.5, f64::NAN] {
        let e = CanNode::new(CanNodeConfig {
            sync_timeout_periods: bad,
            ..CanNodeConfig::servo(id(8))
        })
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "CANopen node 8: sync_timeout_periods = {bad}: the SYNC watchdog's margin \
                 must be at least 1 communication cycle period"
            )
        );
    }
}

#[test]
fn rpdo_event_timer_is_a_deadline() {
    let mut r = Rig::new(&[9]);
    // Only the deadline: 0x2010 off, RPDO1 within 5 ms of the last.
    r.m.write(9, 0x2010, 0, &0u16.to_le_bytes()).unwrap();
    r.m.write(9, 0x1400, 5, &5u16.to_le_bytes()).unwrap();
    assert_eq!(r.m.read(9, 0x1400, 0).unwrap(), [5]);
    assert_eq!(
        r.m.read(9, 0x1400, 3),
        Err(gantry_drives::canopen::sdo::AbortCode::SUB_INDEX_DOES_NOT_EXIST),
        "no inhibit time on an RPDO"
    );
    r.enable();
    let p = r.axes[0].pos;
    // RPDOs every 4 ms are within the deadline.
    for k in 0..40 {
        let c = (k % 4 == 0).then_some((0x0F, p));
        r.cycle(&[c]);
    }
    assert!(r.emcy.is_empty(), "{:?}", r.emcy);
    assert_eq!(r.servo(0).state(), State::OperationEnabled);
    // Then none: the timeout 5 ms after the last one.
    r.cycle(&[Some((0x0F, p))]);
    let last = r.last_frame_at(0x209);
    for _ in 0..10 {
        r.cycle(&[None]);
    }
    assert_eq!(r.emcy.len(), 1, "{:?}", r.emcy);
    let (at, e) = r.emcy[0];
    assert_eq!(e.error_code, 0x8250);
    assert!(
        at >= last + 5 * MS && at <= last + 6 * MS + 135_000,
        "{} ns after the last RPDO",
        at - last
    );
    assert!(matches!(
        r.servo(0).state(),
        State::Fault | State::FaultReactionActive
    ));
}
