//! `physid fmu export`: the virtual test cell as an FMU — FMI 2.0 or 3.0 co-simulation, the
//! description from the cell's own tables, the shared library `physid-fmu` built beside this
//! binary, the scenario in its resources (docs/fmu.md).

use super::simulate::SetArgs;
use crate::out::outln;
use miette::{miette, Result};
use physid_fmu::description::Fmi;
use physid_fmu::variables::{table, Causality};
use physid_fmu::Cell;
use physid_sim::scenario::{Fault, Scenario};
use std::path::{Path, PathBuf};

/// Arguments of `physid fmu`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    action: Action,
}

#[derive(clap::Subcommand)]
enum Action {
    /// Write the cell with a scenario as an FMU.
    ///
    /// Example: physid fmu export --scenario shaft-steady --fmu cell.fmu --fmi 3 --set shaft.k=1100
    Export(Export),
}

/// Arguments of `physid fmu export`.
#[derive(clap::Args)]
struct Export {
    /// Scenario: a built-in name (physid simulate --list) or a TOML file. Its profiles drive
    /// the cell unless the importer sets demand.from_scenario = false.
    #[arg(long)]
    scenario: String,
    /// The FMU to write (.fmu). (`--out` names a report directory in physid's vocabulary.)
    #[arg(long, value_name = "FILE")]
    fmu: PathBuf,
    /// FMI version: 2 (2.0, what most importers take) or 3 (3.0).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    fmi: u8,
    #[command(flatten)]
    set: SetArgs,
    /// Fault PATH=VALUE@T[+RAMP] (repeatable), scheduled in the FMU as in physid simulate.
    #[arg(long = "fault", value_name = "SPEC")]
    faults: Vec<String>,
    /// The outputs' sample rate [Hz] (a communication point reads the sample at or before it).
    #[arg(long, value_name = "HZ", default_value_t = 10_000.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    sample_rate: f64,
    /// The default experiment's stop time [s] (default: the scenario's duration).
    #[arg(long, value_name = "S", value_parser = super::range::positive, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// The FMU's shared library (default: $PHYSID_FMU_LIBRARY, else libphysid_fmu.so beside
    /// this binary, as `cargo build --release -p physid -p physid-fmu` leaves it).
    #[arg(long, value_name = "FILE", env = "PHYSID_FMU_LIBRARY")]
    library: Option<PathBuf>,
    /// Print what was written as JSON.
    #[arg(long)]
    json: bool,
}

/// The library's file name as cargo builds it.
const LIBRARY: &str = "libphysid_fmu.so";

/// Where the shared library is: the one given, else beside this binary or in its `deps/`
/// (where cargo builds it as physid's dependency), the newer of the two (the one beside it is
/// left from the last `cargo build -p physid-fmu` and may be stale).
fn find_library(given: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = given {
        return Ok(p.to_path_buf());
    }
    let exe = std::env::current_exe().map_err(|e| miette!("where is physid? {e}"))?;
    let dir = exe.parent().unwrap_or(Path::new("."));
    [dir.join(LIBRARY), dir.join("deps").join(LIBRARY)]
        .into_iter()
        .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
        .max_by_key(|(modified, _)| *modified)
        .map(|(_, p)| p)
        .ok_or_else(|| {
            miette!(
                "the FMU's shared library {LIBRARY} is not beside physid ({}): build it with `cargo build --release -p physid -p physid-fmu` (it lands beside the binary), or give --library FILE",
                dir.display()
            )
        })
}

/// The library's bytes, checked: a linux x86-64 shared object with both FMI versions'
/// functions.
fn read_library(path: &Path) -> Result<Vec<u8>> {
    let bytes = std::fs::read(path).map_err(|e| miette!("--library {}: {e}", path.display()))?;
    // ELF, 64-bit, little-endian; e_machine x86-64 (62) at byte 18.
    let elf = bytes.len() > 20 && bytes[..4] == *b"\x7fELF" && bytes[4] == 2 && bytes[5] == 1;
    if !elf || u16::from_le_bytes([bytes[18], bytes[19]]) != 62 {
        return Err(miette!(
            "--library {}: not a linux x86-64 shared library",
            path.display()
        ));
    }
    let has = |s: &[u8]| bytes.windows(s.len()).any(|w| w == s);
    for symbol in ["fmi2DoStep", "fmi3DoStep"] {
        if !has(symbol.as_bytes()) {
            return Err(miette!(
                "--library {}: no {symbol}: not physid's FMU library (libphysid_fmu.so)",
                path.display()
            ));
        }
    }
    Ok(bytes)
}

/// The instruction-set extensions beyond x86-64-v2 this build uses: the library, built in the
/// same cargo run with the same flags (.cargo/config.toml builds for the building machine's
/// CPU), needs them too, and an importer on an older CPU would stop on an illegal instruction.
fn beyond_v2() -> Vec<&'static str> {
    [
        ("avx", cfg!(target_feature = "avx")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
        ("bmi2", cfg!(target_feature = "bmi2")),
        ("avx512f", cfg!(target_feature = "avx512f")),
    ]
    .into_iter()
    .filter(|f| f.1)
    .map(|f| f.0)
    .collect()
}

/// Run `physid fmu`.
pub fn run(args: &Args) -> Result<()> {
    match &args.action {
        Action::Export(e) => export(e),
    }
}

fn export(args: &Export) -> Result<()> {
    if args.fmu.extension().and_then(|e| e.to_str()) != Some("fmu") {
        return Err(miette!(
            "--fmu {}: an FMU's file name ends in .fmu",
            args.fmu.display()
        ));
    }
    let mut scenario = Scenario::load(&args.scenario).map_err(|e| miette!("--scenario {e}"))?;
    // The command line's --set wins over the scenario's own settings, as in physid simulate.
    scenario.set.extend(args.set.pairs()?);
    if let Some(d) = args.duration {
        scenario.duration = d;
    }
    for text in &args.faults {
        let f = Fault::parse(text).map_err(|e| miette!("--fault {e}"))?;
        if f.at >= scenario.duration {
            return Err(miette!(
                "--fault {text}: at {} s, after the experiment's stop time ({} s): it would never happen",
                f.at,
                scenario.duration
            ));
        }
        scenario.faults.push(text.clone());
    }
    // A recorded profile goes into the FMU with its points (its CSV file stays behind).
    for p in [&mut scenario.speed, &mut scenario.throttle] {
        for seg in &mut p.segments {
            if let physid_sim::scenario::Shape::Recorded { file, .. } = &mut seg.shape {
                file.clear();
            }
        }
    }
    let cell = Cell::new(scenario, args.sample_rate).map_err(|e| miette!("{e}"))?;
    let library = find_library(args.library.as_deref())?;
    let bytes = read_library(&library)?;
    let fmi = if args.fmi == 3 { Fmi::V3 } else { Fmi::V2 };
    physid_fmu::archive::write(&cell, fmi, &bytes, &args.fmu).map_err(|e| miette!("{e}"))?;
    let extensions = beyond_v2();
    if !extensions.is_empty() {
        eprintln!(
            "warning: {}: built for this machine's CPU ({}): it runs here and on CPUs with the same extensions; for an FMU to give to others, build with RUSTFLAGS=\"-C target-cpu=x86-64-v2\" cargo build --release -p physid -p physid-fmu (docs/fmu.md)",
            args.fmu.display(),
            extensions.join(", ")
        );
    }
    let vars = table(&cell);
    let count = |c: Causality| vars.iter().filter(|v| v.causality == c).count();
    let version = if args.fmi == 3 { "3.0" } else { "2.0" };
    if args.json {
        crate::provenance::print_json_value(serde_json::json!({
            "fmu": args.fmu,
            "fmi": version,
            "model_identifier": physid_fmu::MODEL_IDENTIFIER,
            "guid": cell.guid().map_err(|e| miette!("{e}"))?,
            "scenario": cell.scenario.name,
            "stop_time": cell.scenario.duration,
            "sample_rate": cell.sample_rate,
            "parameters": count(Causality::Parameter),
            "inputs": count(Causality::Input),
            "outputs": count(Causality::Output),
            "library": library,
            "cpu_extensions": extensions,
        }))?;
    } else {
        outln!(
            "wrote {} (FMI {version} co-simulation, linux x86-64; scenario {}, {} s, outputs at {} Hz; {} parameters, {} inputs, {} outputs)",
            args.fmu.display(),
            cell.scenario.name,
            cell.scenario.duration,
            cell.sample_rate,
            count(Causality::Parameter),
            count(Causality::Input),
            count(Causality::Output)
        );
    }
    Ok(())
}
