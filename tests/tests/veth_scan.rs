//! `gantry scan` over a veth pair against `gantry-sim` (README, "On a real (or virtual)
//! wire"): one row per slave with position, station address, alias, vendor, product,
//! revision, serial, name, AL state, DC support and process data sizes, as text and as
//! JSON; the slaves are left in Init. The expected identities come from the simulator's
//! own catalog (the same chain file built in this process). Needs root; `deploy/test.sh`
//! runs it.

use std::process::Command;

use gantry_sim::config::SimConfig;
use gantry_tests::netns::{built_binary, start_gantry_sim_reporting, VethPair};

const SIM: &str = r#"
cycle_us = 1000
[[slave]]
kind = "servo"
[[slave]]
kind = "encoder"
counts_per_rev = 4096
[[slave]]
kind = "switches"
axis = 0
"#;

#[test]
#[ignore = "needs root (network namespaces) and the built binaries; deploy/test.sh runs it"]
fn gantry_scan_lists_what_is_on_the_wire() {
    let pair = VethPair::create("scan").expect("veth pair in two namespaces");
    let dir = std::env::temp_dir().join(format!("gantry-veth-scan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sim_toml = dir.join("sim.toml");
    std::fs::write(&sim_toml, SIM).unwrap();
    let chain = SimConfig::load(sim_toml.to_str().unwrap())
        .unwrap()
        .chain()
        .unwrap();
    let sim = start_gantry_sim_reporting(&pair.sim_ns, &pair.sim_if, &sim_toml, 3);
    let gantry = built_binary("gantry").unwrap();
    let pcap = dir.join("scan.pcap");
    let scan = |json: bool| {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", &pair.master_ns])
            .arg(&gantry)
            .args(["scan", "--interface", &pair.master_if]);
        if json {
            c.arg("--json").arg("--pcap").arg(&pcap);
        }
        let out = c.output().unwrap();
        assert!(
            out.status.success(),
            "gantry scan: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let table = scan(false);
    eprintln!("{table}");
    let rows: serde_json::Value = serde_json::from_str(&scan(true)).expect("JSON");
    let summary = sim.stop().unwrap();
    let rows = rows.as_array().expect("one row per slave");
    assert_eq!(rows.len(), 3, "{rows:?}");
    // Only the servo has distributed clocks (64-bit system time).
    let dc = ["Bits64", "None", "None"];
    // Process data sizes in SafeOp, before `gantry run` maps anything: the PDOs the
    // EEPROM describes (for the servo, its default mapping, which its EEPROM lists too).
    let bytes = |pdos: &[gantry_sim::esc::sii::PdoDescription]| -> u64 {
        let bits: u64 = pdos
            .iter()
            .flat_map(|p| &p.entries)
            .map(|e| u64::from(e.bits))
            .sum();
        bits.div_ceil(8)
    };
    for (i, row) in rows.iter().enumerate() {
        let d = chain.slaves()[i].description();
        assert_eq!(row["position"], i, "{row}");
        assert_eq!(row["address"], 0x1000 + i, "{row}");
        assert_eq!(row["alias"], 0, "{row}");
        assert_eq!(row["vendor"], d.vendor_id, "{row}");
        assert_eq!(row["product"], d.product_code, "{row}");
        assert_eq!(row["revision"], d.revision, "{row}");
        assert_eq!(row["serial"], d.serial, "{row}");
        // ethercrab's name is the EEPROM's order code (ETG.2010 General OrderIdx).
        assert_eq!(row["name"], d.order_code.as_str(), "{row}");
        assert_eq!(row["state"], "Safe-Operational", "{row}");
        assert_eq!(row["dc"], dc[i], "{row}");
        // The servo's PDOs are CoE objects, not in its EEPROM: its default mapping is
        // 0x1600 = controlword + target position, 0x1A00 = statusword + position actual
        // (`gantry_sim::coe::od`), 6 bytes each way.
        let (inputs, outputs) = if d.mailbox.is_some() {
            (6, 6)
        } else {
            (bytes(&d.tx_pdos), bytes(&d.rx_pdos))
        };
        assert_eq!(row["inputs"], inputs, "{row}");
        assert_eq!(row["outputs"], outputs, "{row}");
        assert!(row["inputs"].as_u64() > Some(0), "{row}");
        // The table says the same.
        let line = table.lines().nth(i + 1).unwrap_or_default();
        assert!(line.contains(&d.order_code), "{line}");
        assert!(line.contains(&format!("{:#x}", 0x1000 + i)), "{line}");
    }
    assert!(table.lines().next().unwrap().contains("pos"), "{table}");
    // Left in Init: the last AL control write to each slave, as it came back (the frames
    // the slaves forwarded carry the locally administered source bit), asks for Init
    // (0x0001) and was taken (working counter 1).
    let out = Command::new("tshark")
        .arg("-r")
        .arg(&pcap)
        .args([
            "-Y",
            "ecat.ado == 0x0120 && ecat.cmd == 5 && eth.src == 12:10:10:10:10:10",
            "-T",
            "fields",
            "-e",
            "ecat.adp",
            "-e",
            "ecat.reg.alctrl",
            "-e",
            "ecat.cnt",
        ])
        .output()
        .expect("tshark (deploy/test.sh installs it)");
    let writes = String::from_utf8_lossy(&out.stdout);
    for station in ["0x1000", "0x1001", "0x1002"] {
        let last = writes
            .lines()
            .rfind(|l| l.starts_with(station))
            .unwrap_or_else(|| panic!("no AL control write to {station}: {writes}"));
        let fields: Vec<&str> = last.split('\t').collect();
        assert_eq!(
            fields.get(1..),
            Some(&["0x0001", "1"][..]),
            "{station}: {last}"
        );
    }
    eprintln!("{}", summary.line);
    std::fs::remove_dir_all(&dir).unwrap();
}
