//! The `.fmu` archive: a zip with the description, the shared library under the FMI version's
//! platform directory, and the cell in `resources/` (the scenario as a physid scenario file,
//! and the export's settings).

use crate::description::{model_description, Fmi};
use crate::{Cell, MODEL_IDENTIFIER, SCENARIO_FILE, SETTINGS_FILE};
use std::io::Write;
use std::path::Path;
use zip::write::SimpleFileOptions;

/// Write the FMU of `cell` for FMI `fmi` to `out`, with `library` (this crate built as a
/// linux x86-64 `cdylib`) as its binary. The archive is written to a temporary file beside
/// `out` and renamed: an interrupted export never leaves a half-written FMU.
pub fn write(cell: &Cell, fmi: Fmi, library: &[u8], out: &Path) -> Result<(), String> {
    let description = model_description(cell, fmi)?;
    let dir = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .ok_or_else(|| format!("{}: not a file name", out.display()))?;
    let part = dir.join(format!(".{name}.part"));
    let written = write_zip(cell, fmi, library, &description, &part);
    if written.is_err() {
        let _ = std::fs::remove_file(&part);
    }
    written?;
    std::fs::rename(&part, out).map_err(|e| format!("{}: {e}", out.display()))
}

/// The archive's entries into `part`, synced.
fn write_zip(
    cell: &Cell,
    fmi: Fmi,
    library: &[u8],
    description: &str,
    part: &Path,
) -> Result<(), String> {
    let what = |e: &dyn std::fmt::Display| format!("{}: {e}", part.display());
    let file = std::fs::File::create(part).map_err(|e| what(&e))?;
    let mut zip = zip::ZipWriter::new(file);
    let opts = SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let binary = format!("{}/{MODEL_IDENTIFIER}.so", fmi.platform_dir());
    let (scenario, settings) = (cell.scenario_toml()?, cell.settings_toml()?);
    let entries: [(&str, &[u8], u32); 4] = [
        ("modelDescription.xml", description.as_bytes(), 0o644),
        (&binary, library, 0o755),
        (
            &format!("resources/{SCENARIO_FILE}"),
            scenario.as_bytes(),
            0o644,
        ),
        (
            &format!("resources/{SETTINGS_FILE}"),
            settings.as_bytes(),
            0o644,
        ),
    ];
    for (path, bytes, mode) in entries {
        zip.start_file(path, opts.unix_permissions(mode))
            .map_err(|e| what(&e))?;
        zip.write_all(bytes).map_err(|e| what(&e))?;
    }
    let file = zip.finish().map_err(|e| what(&e))?;
    file.sync_all().map_err(|e| what(&e))
}
