//! `gantry-sim eds --config FILE --node N --out FILE`: the binary writes the EDS of the
//! chain's node N, which gantry's reader reads back as the model of that node; a node
//! the chain does not have is refused with the ids it has.

use std::process::Command;

use gantry_drives::canopen::eds::{self, PdoDirection};
use gantry_sim::config::SimConfig;

const CHAIN: &str = r#"
[[slave]]
kind = "servo"
node = 3

[[slave]]
kind = "encoder"
node = 4

[[slave]]
kind = "switches"
node = 5
axis = 0
[[slave.cam]]
input = 2
from = -100
to = 100
"#;

fn dir(test: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("gantry-sim-eds-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn writes_the_eds_of_each_node_of_the_chain() {
    let d = dir("each");
    let config = d.join("chain.toml");
    std::fs::write(&config, CHAIN).unwrap();
    let chain = SimConfig::parse(CHAIN, "chain.toml").unwrap();
    for (node, product) in [(3u8, 0x402u32), (4, 0x5101), (5, 0x1008)] {
        let out = d.join(format!("node{node}.eds"));
        let run = Command::new(env!("CARGO_BIN_EXE_gantry-sim"))
            .args(["eds", "--config", config.to_str().unwrap(), "--node"])
            .arg(node.to_string())
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(run.status.success(), "{run:?}");
        let read = eds::load(&out).unwrap_or_else(|e| panic!("{e}"));
        let name = format!("node{node}.eds");
        let want = gantry_sim::canopen::eds::for_chain_node(&chain, node, &name).unwrap();
        assert_eq!(read.objects, want.objects, "node {node}");
        assert_eq!(read.device_info, want.device_info);
        assert_eq!(read.device_info.product_number, Some(product));
        assert_eq!(read.file_info.file_name, name);
        assert!(read.max_pdos(PdoDirection::Transmit) == 4);
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_node_the_chain_does_not_have_is_refused() {
    let d = dir("refused");
    let config = d.join("chain.toml");
    std::fs::write(&config, CHAIN).unwrap();
    let out = d.join("x.eds");
    let run = Command::new(env!("CARGO_BIN_EXE_gantry-sim"))
        .args([
            "eds",
            "--config",
            config.to_str().unwrap(),
            "--node",
            "9",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("no slave of the chain has node = 9 (the slaves' node ids: 3, 4, 5)"),
        "{err}"
    );
    assert!(!out.exists());
    // Missing arguments: clap's usage, not a panic.
    let run = Command::new(env!("CARGO_BIN_EXE_gantry-sim"))
        .args(["eds", "--node", "3"])
        .output()
        .unwrap();
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("--config"));
    std::fs::remove_dir_all(&d).unwrap();
}
