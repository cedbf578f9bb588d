//! The `gantry` command line.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};
use gantry::cli::profile::{self, Request};
use gantry::cli::scan;
use gantry::demo::{self, DemoArgs};

/// gantry: a Linux motion master for CiA-402 drives.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Run the scripted demo on simulated axes; writes a trace (CSV) and a plot (SVG).
    Demo {
        /// Folder for trace.csv and plot.svg.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
        /// Simulated seconds per wall-clock second (0: as fast as possible).
        #[arg(long, default_value_t = 4.0)]
        speed: f64,
        /// `sim`: kernel-simulated axes; `ethercat`: simulated CiA-402 drives on an
        /// in-process EtherCAT network, brought up and driven by the master.
        #[arg(long, default_value = "sim", value_parser = ["sim", "ethercat"])]
        bus: String,
        /// With `--bus ethercat`: write every frame sent and received to this pcap file.
        #[arg(long)]
        pcap: Option<PathBuf>,
    },
    /// List the EtherCAT slaves on a network interface (needs CAP_NET_RAW).
    Scan {
        /// Network interface wired to the slaves.
        #[arg(long)]
        interface: String,
        /// Print JSON (one array) instead of a table.
        #[arg(long)]
        json: bool,
        /// Write every frame sent and received to this pcap file.
        #[arg(long)]
        pcap: Option<String>,
    },
    /// Print the planned profile of one move as JSON.
    Profile {
        /// Start position.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        from_pos: f64,
        /// Start velocity.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        from_vel: f64,
        /// Start acceleration.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        from_acc: f64,
        /// Target position.
        #[arg(long, allow_negative_numbers = true, required_unless_present = "batch")]
        to_pos: Option<f64>,
        /// Maximum speed.
        #[arg(long, allow_negative_numbers = true, required_unless_present = "batch")]
        vmax: Option<f64>,
        /// Maximum acceleration.
        #[arg(long, allow_negative_numbers = true, required_unless_present = "batch")]
        amax: Option<f64>,
        /// Maximum deceleration (default: amax).
        #[arg(long, allow_negative_numbers = true)]
        dmax: Option<f64>,
        /// Maximum jerk (S-curve).
        #[arg(long, allow_negative_numbers = true)]
        jmax: Option<f64>,
        /// scurve, trapezoid, sine or linear-sine.
        #[arg(long, default_value = "scurve")]
        ramp: String,
        /// Read one JSON request per line from stdin, write one JSON answer per line.
        #[arg(long)]
        batch: bool,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Cmd::Demo {
            out,
            speed,
            bus,
            pcap,
        } => {
            anyhow::ensure!(
                pcap.is_none() || bus == "ethercat",
                "--pcap needs --bus ethercat (the simulated-axes demo has no bus)"
            );
            anyhow::ensure!(
                speed.is_finite() && speed >= 0.0,
                "--speed {speed} must be >= 0"
            );
            let args = DemoArgs {
                out,
                speed,
                pcap,
                ..DemoArgs::default()
            };
            let mut stdout = std::io::stdout();
            let report = if bus == "ethercat" {
                demo::ethercat::run(&args, &mut stdout)?
            } else {
                demo::run(&args, &mut stdout)?
            };
            writeln!(
                stdout,
                "\ndemo done: {:.2} s simulated in {} cycles of {} ms\ntrace: {}\nplot:  {}",
                report.simulated_s,
                report.cycles,
                args.cycle_s * 1e3,
                report.csv.display(),
                report.svg.display()
            )?;
        }
        Cmd::Scan {
            interface,
            json,
            pcap,
        } => {
            let rows = scan::scan(&interface, pcap.as_deref())?;
            let mut stdout = std::io::stdout();
            if json {
                serde_json::to_writer_pretty(&mut stdout, &rows)?;
                writeln!(stdout)?;
            } else {
                scan::print_table(&rows, &mut stdout)?;
            }
        }
        Cmd::Profile {
            from_pos,
            from_vel,
            from_acc,
            to_pos,
            vmax,
            amax,
            dmax,
            jmax,
            ramp,
            batch,
        } => {
            if batch {
                let stdin = std::io::stdin();
                profile::batch(stdin.lock(), std::io::stdout().lock()).context("batch I/O")?;
                return Ok(());
            }
            let amax = amax.context("--amax is required")?;
            let req = Request {
                from_pos,
                from_vel,
                from_acc,
                to_pos: to_pos.context("--to-pos is required")?,
                vmax: vmax.context("--vmax is required")?,
                amax,
                dmax: dmax.unwrap_or(amax),
                jmax,
                ramp,
            };
            let answer =
                profile::answer(&req, true).map_err(|e| anyhow::anyhow!("gantry profile: {e}"))?;
            println!("{}", serde_json::to_string_pretty(&answer)?);
        }
    }
    Ok(())
}
