//! The bus-load check at configuration: a CANopen cycle's frames — every drive's RPDOs,
//! the SYNC, every drive's TPDOs, the nodes' and gantry's own heartbeats averaged over the
//! cycles — must fit
//! the time the cycle waits for its replies at the configured bit rate, or the
//! configuration is refused with the figures. Each frame is counted at its worst-case
//! length with stuff bits ([`frame_bits`]: 135 bits for 8 data bytes, so 1 Mbit/s
//! carries about 7 such frames per millisecond). EMCYs (sporadic) and the SDO round trip
//! of a drive being restored (it has no PDOs meanwhile) are not counted.
//!
//! Figures (CSP layouts, heartbeat every 100 ms, 1 ms cycle, whose replies are waited for
//! 950 µs): the minimal layout (controlword + target / statusword + actual, one 6-byte
//! PDO each way, 230 bits a drive) fits 3 drives at 1 Mbit/s (748 bits) but not 4 (979
//! bits: 1.03 Mbit/s in 950 µs); the full CSP layout (one 7-byte RPDO, TPDOs of 8 and 7
//! bytes, 385 bits a drive) fits 2 (827 bits), and 4 need a 2 ms cycle (1602 bits in
//! 1.95 ms: 0.82 Mbit/s). A SYNC counter adds 10 bits a cycle.

use std::fmt;

use gantry_drives::canopen::frame::frame_bits;
use thiserror::Error;

use super::pdo::{DrivePlan, PlanError};
use crate::config::Config;
use crate::runtime::clock::reply_window_ns;

/// Bits of a SYNC without counter (0 data bytes).
pub const SYNC_BITS: u64 = frame_bits(0);
/// Bits of a SYNC with counter (1 data byte).
pub const SYNC_COUNTER_BITS: u64 = frame_bits(1);
/// Bits of a heartbeat (1 data byte).
pub const HEARTBEAT_BITS: u64 = frame_bits(1);

/// Why a configuration's frames cannot run on its bus.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum LoadError {
    /// An axis' layout does not fit a node's PDOs.
    #[error("axis {axis:?}: pdo = {pdo:?}: {source}")]
    Layout {
        /// The axis.
        axis: String,
        /// Its layout's name.
        pdo: String,
        /// Why.
        source: PlanError,
    },
    /// An axis' `pdo` names no layout.
    #[error("axis {axis:?}: {reason}")]
    Pdo {
        /// The axis.
        axis: String,
        /// Why.
        reason: String,
    },
    /// The frames do not fit the bit rate.
    #[error("{0}")]
    Overloaded(BusLoad),
}

/// What one cycle puts on the bus.
#[derive(Clone, Debug, PartialEq)]
pub struct BusLoad {
    /// Nodes: the drives, then the I/O modules.
    pub drives: usize,
    /// Of which I/O modules (CiA 401, the switches'), counted last.
    pub modules: usize,
    /// PDOs of each drive (RPDOs + TPDOs), in axis order, then of each I/O module.
    pub pdos: Vec<usize>,
    /// Bits a cycle's frames take at worst: SYNC, PDOs, heartbeats averaged.
    pub bits: u64,
    /// Of which the heartbeats, averaged over the cycles (bits, fractional).
    pub heartbeat_bits: f64,
    /// The cycle time (ns).
    pub period_ns: u64,
    /// The bit rate (bit/s).
    pub bitrate: u32,
    /// The interface's name (for the message).
    pub interface: String,
}

impl BusLoad {
    /// The load of `config`'s axes and the I/O modules their switches read on its bus
    /// (CANopen: `bitrate` given).
    pub fn of_config(config: &Config) -> Result<Self, LoadError> {
        let mut plans = Vec::with_capacity(config.axes.len());
        for a in config
            .axes
            .iter()
            .filter(|a| a.axis_type == crate::config::AxisType::Real)
        {
            let layout = a.pdo_layout().map_err(|(_, reason)| LoadError::Pdo {
                axis: a.name.clone(),
                reason,
            })?;
            let plan = DrivePlan::of(&layout).map_err(|source| LoadError::Layout {
                axis: a.name.clone(),
                pdo: a.pdo.clone(),
                source,
            })?;
            plans.push(plan);
        }
        // The I/O modules the switches read: their TPDO and heartbeat are on the bus too.
        let modules = config.module_nodes();
        for m in &modules {
            plans.push(super::io_module::plan(m)?);
        }
        let mut load = Self::of(
            &plans,
            u64::from(config.bus.cycle_us) * 1000,
            config.bus.bitrate.unwrap_or(0),
            u64::from(config.bus.heartbeat_producer_ms()) * 1_000_000,
            config
                .bus
                .interface
                .clone()
                .unwrap_or_else(|| "the bus".into()),
        );
        load.modules = modules.len();
        Ok(if config.bus.sync_counter.is_some() {
            load.with_sync_counter()
        } else {
            load
        })
    }

    /// The SYNC carries a counter (one data byte more).
    pub fn with_sync_counter(mut self) -> Self {
        self.bits = self.bits - SYNC_BITS + SYNC_COUNTER_BITS;
        self
    }

    /// The load of drives with these PDOs, cycling every `period_ns`, each node and gantry
    /// sending a heartbeat every `heartbeat_ns` (0: none).
    pub fn of(
        plans: &[DrivePlan],
        period_ns: u64,
        bitrate: u32,
        heartbeat_ns: u64,
        interface: String,
    ) -> Self {
        let pdo_bits: u64 = plans.iter().map(DrivePlan::bits_per_cycle).sum();
        let heartbeat_bits = if heartbeat_ns == 0 {
            0.0
        } else {
            // The nodes' and gantry's own (CiA 301 §7.2.8.3.2.2: the master produces one
            // the nodes consume).
            (plans.len() + 1) as f64 * HEARTBEAT_BITS as f64 * period_ns as f64
                / heartbeat_ns as f64
        };
        Self {
            drives: plans.len(),
            modules: 0,
            pdos: plans.iter().map(DrivePlan::pdo_count).collect(),
            bits: SYNC_BITS + pdo_bits + heartbeat_bits.ceil() as u64,
            heartbeat_bits,
            period_ns,
            bitrate,
            interface,
        }
    }

    /// Bits left in a cycle's window beside its SYNC and PDOs (worst case): what an SDO
    /// transfer may put on the bus per cycle, its frames and the node's answers, without
    /// delaying the process data — less the heartbeats in the cycles they come in (every
    /// few hundred cycles, all at once: the bus keeps them free).
    pub fn spare_bits(&self) -> u64 {
        let window_bits = u128::from(self.window_ns()) * u128::from(self.bitrate) / 1_000_000_000;
        let cyclic = self.bits.saturating_sub(self.heartbeat_bits.ceil() as u64);
        u64::try_from(window_bits.saturating_sub(u128::from(cyclic))).unwrap_or(u64::MAX)
    }

    /// How long the cycle waits for its frames (ns; [`reply_window_ns`]).
    pub fn window_ns(&self) -> u64 {
        reply_window_ns(self.period_ns)
    }

    /// The bit rate the frames need to fit the window (bit/s).
    pub fn needed_bitrate(&self) -> f64 {
        self.bits as f64 * 1e9 / self.window_ns().max(1) as f64
    }

    /// The share of the window the frames take at the bit rate (1.0 = all of it).
    pub fn utilisation(&self) -> f64 {
        self.needed_bitrate() / f64::from(self.bitrate.max(1))
    }

    /// Refuses a load over the bit rate.
    pub fn check(self) -> Result<Self, LoadError> {
        if self.needed_bitrate() > f64::from(self.bitrate) {
            Err(LoadError::Overloaded(self))
        } else {
            Ok(self)
        }
    }
}

/// A bit rate in the unit that reads best.
fn rate(bits_per_s: f64) -> String {
    if bits_per_s >= 1e6 {
        format!("{} Mbit/s", round(bits_per_s / 1e6))
    } else {
        format!("{} kbit/s", round(bits_per_s / 1e3))
    }
}

/// Two decimals, without trailing zeros.
fn round(x: f64) -> String {
    let s = format!("{x:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

impl fmt::Display for BusLoad {
    /// "4 drives × 2 PDOs + SYNC at 1 kHz need 1.03 Mbit/s (979 bits in the 950 µs the
    /// cycle waits for its TPDOs); can0 has 1 Mbit/s".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.drives.saturating_sub(self.modules);
        let drives = if n == 1 { "drive" } else { "drives" };
        let modules = match self.modules {
            0 => String::new(),
            1 => " + 1 I/O module".into(),
            m => format!(" + {m} I/O modules"),
        };
        match self.pdos.first() {
            Some(&k) if self.pdos.iter().all(|&n| n == k) => {
                write!(f, "{n} {drives}{modules} × {k} PDOs")?
            }
            _ => write!(
                f,
                "{n} {drives}{modules} with {} PDOs",
                self.pdos.iter().sum::<usize>()
            )?,
        }
        let hz = 1e9 / self.period_ns.max(1) as f64;
        let at = if hz >= 1000.0 {
            format!("{} kHz", round(hz / 1000.0))
        } else {
            format!("{} Hz", round(hz))
        };
        write!(
            f,
            " + SYNC at {at} need {} ({} bits in the {} µs the cycle waits for its TPDOs, \
             heartbeats included); {} has {}",
            rate(self.needed_bitrate()),
            self.bits,
            self.window_ns() / 1000,
            self.interface,
            rate(f64::from(self.bitrate)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::cia402::pdo::PdoLayout;

    fn load(n: usize, layout: PdoLayout, cycle_us: u64, bitrate: u32) -> BusLoad {
        let plans = vec![DrivePlan::of(&layout).unwrap(); n];
        BusLoad::of(&plans, cycle_us * 1000, bitrate, 100_000_000, "can0".into())
    }

    #[test]
    fn three_minimal_drives_fit_1_mbit_at_1_ms_and_four_do_not() {
        let three = load(3, PdoLayout::csp_minimal(), 1000, 1_000_000);
        // SYNC 55 + 3 × (115 + 115) + 3 heartbeats and gantry's of 65 bits every 100
        // cycles.
        assert_eq!(three.bits, 55 + 690 + 3);
        assert!((three.heartbeat_bits - 2.6).abs() < 1e-9);
        assert_eq!(three.window_ns(), 950_000);
        assert!(three.utilisation() < 0.8, "{}", three.utilisation());
        assert!(three.clone().check().is_ok());
        let four = load(4, PdoLayout::csp_minimal(), 1000, 1_000_000);
        assert_eq!(four.bits, 55 + 920 + 4);
        assert_eq!(
            four.check().unwrap_err().to_string(),
            "4 drives × 2 PDOs + SYNC at 1 kHz need 1.03 Mbit/s (979 bits in the 950 µs the \
             cycle waits for its TPDOs, heartbeats included); can0 has 1 Mbit/s"
        );
    }

    #[test]
    fn the_full_csp_layout_fits_two_drives_at_1_ms_and_four_at_2_ms() {
        assert!(load(2, PdoLayout::csp(), 1000, 1_000_000).check().is_ok());
        let three = load(3, PdoLayout::csp(), 1000, 1_000_000);
        assert_eq!(three.bits, 55 + 3 * 385 + 3);
        assert!(three.check().is_err());
        let four = load(4, PdoLayout::csp(), 2000, 1_000_000).check().unwrap();
        assert_eq!(four.bits, 55 + 4 * 385 + 7);
        assert_eq!(four.window_ns(), 1_950_000);
        assert!((four.utilisation() - 1602.0 / 1950.0).abs() < 1e-9);
        // A SYNC with counter: one data byte more (65 bits instead of 55).
        assert_eq!(four.with_sync_counter().bits, 65 + 4 * 385 + 7);
    }

    #[test]
    fn an_sdo_transfer_gets_the_bits_left_in_the_window() {
        // 4 full CSP drives at 2 ms: SYNC and PDOs 1595 of 1950 bits, 355 left (two
        // 8-byte frames) when no heartbeat comes.
        let four = load(4, PdoLayout::csp(), 2000, 1_000_000);
        assert_eq!(four.spare_bits(), 355);
        // 1 minimal drive at 1 ms: 950 − 285.
        let one = load(1, PdoLayout::csp_minimal(), 1000, 1_000_000);
        assert_eq!(one.bits, 55 + 230 + 2);
        assert_eq!(one.spare_bits(), 665);
        // An overloaded window leaves nothing.
        assert_eq!(load(8, PdoLayout::csp(), 1000, 1_000_000).spare_bits(), 0);
    }

    #[test]
    fn the_switch_modules_are_counted_and_named() {
        let plain = load(1, PdoLayout::csp(), 1000, 125_000);
        let mut with = BusLoad::of(
            &[
                DrivePlan::of(&PdoLayout::csp()).unwrap(),
                DrivePlan::of(&crate::canopen::io_module::layout(1)).unwrap(),
            ],
            1_000_000,
            125_000,
            100_000_000,
            "can0".into(),
        );
        with.modules = 1;
        // Its TPDO (1 byte) and its heartbeat averaged (65 bits every 100 cycles: 1.95
        // bits a cycle for three heartbeats instead of 1.3, both rounded up to 2).
        assert_eq!(with.bits - plain.bits, frame_bits(1));
        assert!((with.heartbeat_bits - plain.heartbeat_bits - 0.65).abs() < 1e-9);
        let e = with.check().unwrap_err().to_string();
        assert!(
            e.starts_with("1 drive + 1 I/O module with 4 PDOs + SYNC at 1 kHz need"),
            "{e}"
        );
    }

    /// The full CSP layout with switches and both touch probes: 9 output bytes (2 RPDOs),
    /// 37 input bytes (5 TPDOs: four of 8 bytes and one of 5) — every PDO counted.
    #[test]
    fn pdos_beyond_the_fourth_are_counted() {
        let switches: crate::config::SwitchesSection = toml::from_str(
            "negative_limit = \"drive\"\npositive_limit = \"drive\"\nreference = \"drive\"\n\
             probe_source = { negative_limit = -1, positive_limit = -2 }",
        )
        .unwrap();
        let mut layout = PdoLayout::csp();
        switches.extend(&mut layout).unwrap();
        let plan = DrivePlan::of(&layout).unwrap();
        assert_eq!((plan.rpdos.len(), plan.tpdos.len()), (2, 5));
        assert_eq!(plan.bits_per_cycle(), 135 + 65 + 4 * 135 + 105);
        let one = load(1, layout.clone(), 1000, 1_000_000);
        assert_eq!(one.bits, 55 + 845 + 2);
        assert!(one.check().is_ok(), "one drive at 1 ms");
        let e = load(2, layout, 1000, 1_000_000)
            .check()
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("2 drives × 7 PDOs + SYNC at 1 kHz need 1.84 Mbit/s (1747 bits"),
            "{e}"
        );
    }

    #[test]
    fn eight_drives_at_1_khz_name_the_figure() {
        let e = load(8, PdoLayout::csp(), 1000, 1_000_000)
            .check()
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "8 drives × 3 PDOs + SYNC at 1 kHz need 3.31 Mbit/s (3141 bits in the 950 µs the \
             cycle waits for its TPDOs, heartbeats included); can0 has 1 Mbit/s"
        );
        let slow = load(1, PdoLayout::csp(), 250, 125_000)
            .check()
            .unwrap_err()
            .to_string();
        assert!(
            slow.starts_with(
                "1 drive × 3 PDOs + SYNC at 4 kHz need 1.96 Mbit/s (441 bits in the 225 µs"
            ) && slow.ends_with("can0 has 125 kbit/s"),
            "{slow}"
        );
    }
}
