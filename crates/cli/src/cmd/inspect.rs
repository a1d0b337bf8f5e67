//! `physid inspect`: what is in a recording, and the post-run integrity check (thesis ch. 4).

use super::InputArgs;
use crate::out::outln;
use crate::plot;
use crate::progress::Reading;
use crate::report::Report;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::acquisition::{
    inspect_wheel, parse_threshold, AcquisitionOptions, AngleSensor, AngleSpec, Inspector,
    PhaseFrom,
};
use physid_apps::compression::TdcFromPressure;
use physid_core::Recording;
use physid_signal::wheel::{Edge, EdgeOptions};
use std::path::{Path, PathBuf};

/// Arguments of `physid inspect`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording (CSV, Parquet or MDF4).
    pub file: PathBuf,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub angle: AngleArgs,
    /// Exit with an error when the integrity check finds anything.
    #[arg(long)]
    pub strict: bool,
    /// Directory for cycle-by-crank-angle surface views (thesis Fig. 4.8) of --surface channels.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Channels to draw as surfaces (needs crank-angle data: `cycle` and `crank_deg`).
    #[arg(long, value_delimiter = ',')]
    pub surface: Vec<String>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Where the engine angle comes from on a time basis (besides `theta_en`): encoder counts with
/// a TDC marker, or a trigger wheel's raw signal — the same flags in every verb that takes it.
#[derive(clap::Args, Debug, Clone)]
pub struct AngleArgs {
    /// Encoder counter channel and pulses per revolution (repeatable); the TDC marker belongs
    /// to the first [default: count_en=360, count_dy=1024].
    #[arg(long = "encoder", value_name = "CHANNEL=PPR")]
    pub encoders: Vec<String>,
    /// TDC marker channel [default: tdc].
    #[arg(long)]
    pub marker: Option<String>,
    #[command(flatten)]
    pub wheel: WheelArgs,
}

impl Default for AngleArgs {
    /// The thesis's test cell: `count_en` (360 pulses/rev), `count_dy` (1024), marker `tdc`,
    /// no raw sensor — what the flags give when none is set.
    fn default() -> Self {
        Self {
            encoders: Vec::new(),
            marker: None,
            wheel: WheelArgs::default(),
        }
    }
}

impl AngleArgs {
    /// The acquisition options these flags give.
    pub fn options(&self) -> Result<AcquisitionOptions> {
        let marker = self
            .marker
            .as_deref()
            .unwrap_or(physid_apps::acquisition::TDC_MARKER);
        let mut o = acquisition_options(&self.encoders, marker)?;
        o.sensor = self.wheel.spec()?;
        if o.sensor.is_none() {
            o.phase_from = self.wheel.phase();
        }
        Ok(o)
    }

    /// The first of these flags given that only a reading on a crank-angle basis uses (the
    /// engine angle's source and its TDC), to refuse where none is made rather than ignore:
    /// those that decode an angle first, `--phase-from` (which `theta_en` takes too) last.
    pub fn crank_angle_flag(&self) -> Option<&'static str> {
        let w = &self.wheel;
        [
            (w.wheel.is_some(), "--wheel"),
            (w.quadrature.is_some(), "--quadrature"),
            (w.encoder_raw.is_some(), "--encoder-raw"),
            (!self.encoders.is_empty(), "--encoder"),
            (self.marker.is_some(), "--marker"),
            (w.phase_from.is_some(), "--phase-from"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
    }
}

/// Where `--tdc-from CHANNEL` placed the TDC, on stderr: with its interval, the loss angle (or
/// why there is none) and the fired cycles left out.
pub fn tell_tdc_from(input: &Path, channel: &str, found: &TdcFromPressure) {
    let loss = match found.peak_deg {
        Some(p) => format!("the pressure peaks {:.3}° before it (the loss angle)", -p),
        None => {
            "the fitted trace has no peak before it (no loss angle: k_loss not positive)".into()
        }
    };
    let fired = match found.fired_left_out {
        0 => String::new(),
        n => format!("; {n} fired cycle(s) left out"),
    };
    eprintln!(
        "{}: TDC from '{channel}' (the motored model over {} TDCs): {:.3}° after the sensor's reference (95 %: {:.3} … {:.3}°); {loss}{fired}",
        input.display(),
        found.fit.events.len(),
        found.tdc_offset_deg,
        found.ci95.0,
        found.ci95.1,
    );
}

/// A raw angle sensor as the engine angle: a trigger wheel (`physid_signal::wheel`) or a
/// quadrature encoder (`physid_signal::quadrature`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct WheelArgs {
    /// A trigger wheel's raw sensor channel (analog or digital) and the wheel: N tooth pitches,
    /// M missing, e.g. enc=60-2 — decoded into the crank angle.
    #[arg(long, value_name = "CHANNEL=N-M", groups = ["sensor", "edged"])]
    pub wheel: Option<String>,
    /// A single-channel pulse encoder's raw channel (analog or digital, turning forward) and its
    /// pulses per revolution, e.g. enc=360, with its index on --index-raw — decoded into the
    /// crank angle (the wheel's edge detection and glitch rejection; angle 0 the first edge
    /// after the index pulse).
    #[arg(long, value_name = "CHANNEL=PULSES", groups = ["sensor", "edged"], requires = "index_raw")]
    pub encoder_raw: Option<String>,
    /// The index of --encoder-raw: a raw once-per-revolution pulse channel (its level midway
    /// between its smallest and largest sample).
    #[arg(long, value_name = "CHANNEL", requires = "encoder_raw")]
    pub index_raw: Option<String>,
    /// A quadrature encoder's channels A, B and index Z, and its lines per revolution, e.g.
    /// enc_a,enc_b,enc_z=500 — decoded into the crank angle (both ways).
    #[arg(long, value_name = "A,B,Z=LINES", group = "sensor")]
    pub quadrature: Option<String>,
    /// With --wheel, --quadrature or --encoder-raw: the crank angle [deg] from the sensor's
    /// reference (the first tooth edge after the gap; the index pulse; the first pulse edge
    /// after the index pulse) to the next TDC (read it off a plot of the raw signal).
    #[arg(
        long,
        value_name = "DEG",
        requires = "sensor",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub tdc_offset: f64,
    /// Which revolution of two fires — the one whose TDC has the higher mean of CHANNEL over
    /// the revolution around it: the cylinder pressure, or a cam sensor high (or pulsing)
    /// there; CHANNEL:low for a cam that marks the other revolution. With --wheel,
    /// --quadrature or --encoder-raw, over the whole recording; with a TDC marker once per
    /// revolution (with `theta_en` or an encoder's counts), over the first 8 revolutions after
    /// it. By default `p_cyl` when the recording has it (the first TDC taken as firing when it
    /// cannot tell, and said); `none`: the first TDC taken as firing.
    #[arg(long, value_name = "CHANNEL[:low]|none")]
    pub phase_from: Option<String>,
    /// With --wheel or --quadrature: place the TDC from this motored cylinder-pressure channel
    /// instead of --tdc-offset — the motored model's TDC (with the thermodynamic loss angle,
    /// not the pressure's peak), reported with its 95 % interval. Needs --stroke and --rod.
    #[arg(
        long,
        value_name = "CHANNEL",
        requires = "sensor",
        conflicts_with = "tdc_offset"
    )]
    pub tdc_from: Option<String>,
    /// With --wheel or --encoder-raw: the tooth (pulse) edge is the signal rising (a Hall
    /// sensor's tooth) or falling through the level.
    #[arg(
        long,
        value_name = "rising|falling",
        requires = "edged",
        default_value = "rising"
    )]
    pub edge: String,
    /// With --wheel or --encoder-raw: a fixed level and hysteresis (half-band) in the channel's
    /// unit instead of the automatic level that follows the teeth's swing.
    #[arg(long, value_name = "LEVEL,HYSTERESIS", requires = "edged")]
    pub threshold: Option<String>,
}

impl WheelArgs {
    /// The sensor to decode, if one is given.
    pub fn spec(&self) -> Result<Option<AngleSpec>> {
        let sensor = match (&self.wheel, &self.quadrature, &self.encoder_raw) {
            (Some(w), ..) => self.wheel_sensor(w)?,
            (None, Some(q), _) => AngleSensor::parse_quadrature(q).map_err(|e| miette!("--{e}"))?,
            (None, None, Some(e)) => AngleSensor::parse_pulses(
                e,
                self.index_raw.as_deref().unwrap_or_default(),
                self.edge_options()?,
            )
            .map_err(|e| miette!("--{e}"))?,
            (None, None, None) => return Ok(None),
        };
        AngleSpec::new(sensor, self.tdc_offset, self.phase())
            .map(Some)
            .map_err(|e| miette!("--tdc-offset {e}"))
    }

    /// Where which revolution fires is told from (`--phase-from`, `none`, or the default).
    pub fn phase(&self) -> PhaseFrom {
        PhaseFrom::parse(self.phase_from.as_deref())
    }

    fn wheel_sensor(&self, w: &str) -> Result<AngleSensor> {
        AngleSensor::parse_wheel(w, self.edge_options()?).map_err(|e| miette!("--{e}"))
    }

    fn edge_options(&self) -> Result<EdgeOptions> {
        let edge: Edge = self.edge.parse().map_err(|e| miette!("--edge: {e}"))?;
        let threshold = match &self.threshold {
            None => None,
            Some(s) => Some(parse_threshold(s).map_err(|e| miette!("--{e}"))?),
        };
        Ok(EdgeOptions { edge, threshold })
    }
}

/// Encoder options from `CHANNEL=PPR` items (defaults when none).
pub fn acquisition_options(encoders: &[String], marker: &str) -> Result<AcquisitionOptions> {
    let mut o = AcquisitionOptions {
        marker: marker.to_string(),
        ..Default::default()
    };
    if !encoders.is_empty() {
        o.encoders = encoders
            .iter()
            .map(|e| AcquisitionOptions::parse_encoder(e).map_err(|e| miette!("--{e}")))
            .collect::<Result<_>>()?;
    }
    Ok(o)
}

/// Run `physid inspect`.
pub fn run(args: &Args) -> Result<()> {
    if args.angle.wheel.tdc_from.is_some() {
        return Err(miette!(
            "inspect --tdc-from: inspect reports what the wheel shows; the TDC is placed from the pressure by `physid convert --crank-angle`, `cycles` and `compression fit` with --tdc-from"
        ));
    }
    let opts = args.angle.options()?;
    // The file read a chunk at a time: memory does not grow with its length.
    let mut reader = args.input.open_all(&args.file)?;
    match opts.sensor.as_ref().map(|s| &s.sensor) {
        Some(AngleSensor::Wheel { channel, .. }) if reader.header().channel(channel).is_err() => {
            return Err(miette!(
                "{}: --wheel names '{channel}', which the recording does not have; its channels are {}",
                args.file.display(),
                reader.header().names().join(", ")
            ));
        }
        // `convert --crank-angle` and `cycles` decode it and say what they found.
        Some(AngleSensor::Quadrature { .. }) => {
            return Err(miette!(
                "inspect --quadrature: not supported — `physid convert --crank-angle --quadrature …` reports what it finds"
            ));
        }
        Some(AngleSensor::Pulses { channel, index, .. })
            if reader.header().channel(channel).is_err()
                || reader.header().channel(index).is_err() =>
        {
            return Err(miette!(
                "{}: --encoder-raw and --index-raw name '{channel}' and '{index}'; the recording's channels are {}",
                args.file.display(),
                reader.header().names().join(", ")
            ));
        }
        _ => {}
    }
    let mut inspector = Inspector::new(reader.header(), &opts);
    for chunk in Reading::new(&mut reader, &args.file) {
        inspector.push(&chunk.into_diagnostic()?);
    }
    super::warn_read(&reader, &args.file);
    let mut i = inspector.finish();
    let header = reader.header();
    // A wheel named: decoded as it is read again (where the gap is, then every edge's angle).
    if let Some(sensor @ (AngleSensor::Wheel { .. } | AngleSensor::Pulses { .. })) =
        opts.sensor.as_ref().map(|s| &s.sensor)
    {
        let mut names = vec!["t".to_string()];
        names.extend(sensor.channels().into_iter().map(str::to_string));
        let read = args.input.options(Some(names))?;
        inspect_wheel(
            &mut i,
            header,
            &opts,
            &physid_io::FileChunks::new(&args.file, read),
        );
    }
    let samples = reader.rows_read();
    let mut written = Vec::new();
    if let Some(dir) = &args.out {
        written = surfaces(&args.input, &args.file, header, &args.surface, dir)?;
        let mut rep = Report::new("physid — inspect", &format!("{}", args.file.display()));
        rep.section("Channels");
        rep.para(
            &format!(
                "{} basis, {} samples{}{}{}.",
                i.basis,
                samples,
                i.duration_s
                    .map_or(String::new(), |d| format!(", {d:.6} s")),
                i.sample_rate_hz
                    .map_or(String::new(), |r| format!(" at {r:.3} Hz")),
                i.cycles
                    .map_or(String::new(), |c| format!(", {c} complete cycles")),
            ),
            None,
        );
        rep.table(
            &["channel", "unit", "samples"],
            &i.channels
                .iter()
                .map(|c| vec![c.name.clone(), c.unit.clone(), c.samples.to_string()])
                .collect::<Vec<_>>(),
        );
        rep.section("Integrity");
        for n in &i.integrity.notes {
            rep.para(&format!("Note (sample {}): {}", n.index, n.detail), None);
        }
        if i.integrity.ok {
            rep.para("No finding.", Some("ok"));
        } else {
            rep.table(
                &["sample", "kind", "detail"],
                &i.integrity
                    .findings
                    .iter()
                    .map(|f| {
                        vec![
                            f.index.to_string(),
                            serde_json::to_value(f.kind)
                                .ok()
                                .and_then(|v| v.as_str().map(String::from))
                                .unwrap_or_default(),
                            f.detail.clone(),
                        ]
                    })
                    .collect::<Vec<_>>(),
            );
        }
        for w in &written {
            rep.svg(Path::new(w))?;
        }
        rep.write(&dir.join("report.html"))?;
        std::fs::write(
            dir.join("inspect.json"),
            serde_json::to_string_pretty(&crate::provenance::with(&i)).into_diagnostic()?,
        )
        .into_diagnostic()?;
    }
    if args.json {
        let mut v = serde_json::to_value(&i).into_diagnostic()?;
        if let Some(o) = v.as_object_mut() {
            o.insert("surfaces".into(), serde_json::json!(written));
        }
        crate::provenance::print_json_value(v)?;
    } else {
        outln!(
            "{}: {} basis, {} samples",
            args.file.display(),
            i.basis,
            samples
        );
        if let Some(d) = i.duration_s {
            outln!("duration {d:.6} s");
        }
        if let Some(r) = i.sample_rate_hz {
            outln!("sample rate {r:.3} Hz");
        }
        if let Some(c) = i.cycles {
            outln!("complete cycles (720°): {c}");
        }
        if let Some(w) = &i.wheel {
            let what = match &w.index {
                Some(z) => format!("encoder '{}' ({} pulses, index '{z}')", w.channel, w.teeth),
                None => format!("wheel '{}' ({})", w.channel, w.wheel),
            };
            match (&w.error, &w.index) {
                (None, Some(_)) => outln!(
                    "{what}: {} edges, {} revolutions, {:.0}–{:.0} rpm, {} glitch(es) rejected",
                    w.edges,
                    w.revolutions,
                    w.rpm_min,
                    w.rpm_max,
                    w.glitches
                ),
                (Some(e), _) => outln!("{what}: not decoded — {e}"),
                (None, None) => outln!(
                    "wheel '{}' ({}): {} teeth and a gap of {} per revolution, {} edges, {} revolutions, {:.0}–{:.0} rpm, {} glitch(es) rejected",
                    w.channel, w.wheel, w.teeth, w.missing, w.edges, w.revolutions, w.rpm_min, w.rpm_max, w.glitches
                ),
            }
        }
        for w in &i.recognised {
            outln!(
                "'{}' looks like a {} trigger wheel's signal ({} teeth and a gap of {} per revolution, {} gaps seen): decode it with --wheel {}={}",
                w.channel, w.wheel, w.teeth, w.missing, w.gaps, w.channel, w.wheel
            );
        }
        outln!("{:<24} {:<10} {:>10}", "channel", "unit", "samples");
        for c in &i.channels {
            outln!("{:<24} {:<10} {:>10}", c.name, c.unit, c.samples);
        }
        for n in &i.integrity.notes {
            outln!("note: {} (sample {})", n.detail, n.index);
        }
        if let Some(u) = header.meta.get("units_converted") {
            outln!("units converted on reading: {u}");
        }
        if i.integrity.ok {
            outln!("integrity: ok");
        } else {
            outln!("integrity: {} finding(s)", i.integrity.findings.len());
            for f in &i.integrity.findings {
                outln!(
                    "  sample {:>9}  {:<20} {}",
                    f.index,
                    serde_json::to_value(f.kind)
                        .ok()
                        .and_then(|v| v.as_str().map(String::from))
                        .unwrap_or_default(),
                    f.detail
                );
            }
        }
        for w in &written {
            outln!("wrote {w}");
        }
        if let Some(dir) = &args.out {
            outln!("wrote {}", dir.join("report.html").display());
        }
    }
    if args.strict && !i.integrity.ok {
        return Err(miette!(
            "{}: the integrity check found {} problem(s) (--strict)",
            args.file.display(),
            i.integrity.findings.len()
        ));
    }
    Ok(())
}

/// One SVG per channel: rows are cycles, columns crank degrees (the file's `cycle`,
/// `crank_deg` and those channels read whole).
fn surfaces(
    input: &InputArgs,
    file: &Path,
    header: &Recording,
    channels: &[String],
    dir: &Path,
) -> Result<Vec<String>> {
    if channels.is_empty() {
        return Err(miette!(
            "--out draws surfaces: name the channels with --surface p_cyl,…"
        ));
    }
    if header.channel("cycle").is_err() || header.channel("crank_deg").is_err() {
        return Err(miette!(
            "surfaces need crank-angle data with 'cycle' and 'crank_deg' channels: convert first (physid convert IN OUT --crank-angle)"
        ));
    }
    for name in channels {
        header
            .channel(name)
            .map_err(|e| miette!("--surface: {e}"))?;
    }
    let mut names = vec!["cycle".to_string(), "crank_deg".to_string()];
    names.extend(
        channels
            .iter()
            .filter(|n| !names.contains(n))
            .cloned()
            .collect::<Vec<_>>(),
    );
    let rec = input.read(file, Some(names))?;
    let (cycle, deg) = (
        rec.values("cycle").into_diagnostic()?,
        rec.values("crank_deg").into_diagnostic()?,
    );
    crate::report::create_dir(dir)?;
    let mut written = Vec::new();
    for name in channels {
        let x = rec.values(name).map_err(|e| miette!("--surface: {e}"))?;
        let path = dir.join(format!("surface-{name}.svg"));
        let unit = rec
            .channel(name)
            .map(|c| c.unit.clone())
            .unwrap_or_default();
        plot::surface(
            &path,
            &format!("{name} [{unit}] by cycle and crank angle"),
            cycle,
            deg,
            x,
        )?;
        written.push(path.display().to_string());
    }
    Ok(written)
}
