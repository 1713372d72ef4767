//! The `ifd-brush` program: a window on the brush app, or a headless replay.

use ifd_app::{DeviceArg, Shell};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;
use ifd_brush::app::{
    Automation, BrushApp, Persisted, STORAGE_KEY, StartOptions, WindowGpu, bundled_image,
};
use ifd_brush::engine::{Banks, Engine};
use ifd_brush::strokes::StrokesFile;
use ifd_image::MemoryBudget;

/// Paint Hessian-driven anisotropic smoothing onto an image.
///
/// Without options, opens the bundled test image in a window.
#[derive(Parser, Debug)]
#[command(version)]
struct Args {
    /// Image to open (PNG, JPEG, TIFF, EXR, HDR); default: the bundled
    /// test image.
    #[arg(value_name = "IMAGE")]
    image: Option<PathBuf>,
    /// Replay recorded strokes (see the crate docs for the format).
    #[arg(long, value_name = "STROKES.json")]
    replay: Option<PathBuf>,
    /// Record the strokes painted in this session to a file (written on
    /// exit, and after a replay).
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// Save the image here after the replay (PNG, EXR, TIFF by extension).
    #[arg(long, value_name = "OUT")]
    save: Option<PathBuf>,
    /// Take a screenshot of the window once the image is shown (and the replay done).
    #[arg(long, value_name = "PATH.png")]
    screenshot: Option<PathBuf>,
    /// Exit when done. With --replay and without --screenshot, runs without a window.
    #[arg(long)]
    exit: bool,
    /// Aspect-bank cache file (default: `aspect-bank-v1.json` in `$IFD_CACHE_DIR`,
    /// else `$XDG_CACHE_HOME/ifd`, else `~/.cache/ifd`; shared with `ifd smooth`).
    #[arg(long, value_name = "FILE")]
    bank: Option<PathBuf>,
    /// Where dabs are evaluated: auto (a hardware GPU when there is one; a
    /// software adapter such as lavapipe is slower than the CPU path), gpu
    /// (any adapter, software included), cpu.
    #[arg(long, value_enum, default_value_t = DeviceArg::Auto)]
    device: DeviceArg,
    /// Memory budget for images, MiB (default: 75% of physical memory).
    #[arg(long, value_name = "MIB")]
    memory_budget: Option<u64>,
    /// Brush settings for a headless replay's strokes that give none, and
    /// the window's start settings: JSON like {"radius": 20, "mode": "dab"}.
    #[arg(long, value_name = "JSON")]
    brush: Option<String>,
    /// Folder of the edit journals, which save every stroke as you paint so
    /// that a crash loses at most the stroke in progress (default in a
    /// window: ~/.local/state/ifd-brush/journal; headless runs journal only
    /// when this is given).
    #[arg(long, value_name = "DIR", conflicts_with = "no_journal")]
    journal_dir: Option<PathBuf>,
    /// Do not journal edits.
    #[arg(long)]
    no_journal: bool,
    /// Headless: apply the journal an interrupted session left for the image
    /// (before --replay, if given); the window asks instead.
    #[arg(long)]
    recover: bool,
    /// Headless: wait this many milliseconds after each replayed stroke (to
    /// watch a replay's journal, or to interrupt it on purpose).
    #[arg(long, value_name = "MS", default_value_t = 0)]
    replay_pace: u64,
}

fn headless(args: &Args, budget: MemoryBudget) -> anyhow::Result<()> {
    let file = args
        .replay
        .as_ref()
        .map(|p| StrokesFile::load(p))
        .transpose()?;
    let bank_cache = args.bank.clone().or_else(Banks::default_cache);
    let banks = Banks::load_or_build(bank_cache.as_deref(), |d, n| {
        eprintln!("fitting decompositions {d}/{n}");
    })?;
    let mut engine = Engine::new(banks, budget);
    if !args.no_journal {
        engine.set_journal_dir(args.journal_dir.clone(), true);
    }
    let (label, note) = engine.enable_gpu(args.device.into());
    eprintln!(
        "compute: {label}{}",
        note.map(|n| format!(" ({n})")).unwrap_or_default()
    );
    let brush = match &args.brush {
        Some(j) => serde_json::from_str(j).context("parsing --brush")?,
        None => ifd_brush::BrushSettings::default(),
    };
    let path = args.image.clone().unwrap_or_else(bundled_image);
    let loaded = engine.read(&path, &brush)?;
    let float = loaded.integer_bits.is_none();
    engine.set_image(loaded.image, Some(path), float);
    if args.record.is_some() {
        engine.start_recording();
    }
    if let Some(r) = engine.recoverable() {
        let n = r.strokes.strokes.len();
        if args.recover {
            let dabs = engine.resolve_recovery(true)?;
            eprintln!("recovered {n} journal entries ({dabs} dabs)");
        } else {
            eprintln!(
                "note: an interrupted session left {n} edits of this image in the journal; \
                 pass --recover to apply them (nothing is journaled in this run)"
            );
        }
    } else if args.recover {
        eprintln!("note: --recover: no journal of this image to recover");
    }
    let t0 = std::time::Instant::now();
    let mut dabs = 0;
    if let Some(file) = &file {
        if args.replay_pace == 0 {
            dabs = engine.replay(file)?;
        } else {
            // One entry at a time, pausing after each.
            for a in &file.strokes {
                let one = StrokesFile {
                    image_size: file.image_size,
                    strokes: vec![a.clone()],
                    ..StrokesFile::default()
                };
                dabs += engine.replay(&one)?;
                std::thread::sleep(std::time::Duration::from_millis(args.replay_pace));
            }
        }
    }
    // The path can change once the image is prepared (a smoother beyond the
    // device's limits runs on the CPU).
    let (now, why) = engine.compute();
    if now != label {
        eprintln!(
            "compute: {now}{}",
            why.map(|n| format!(" ({n})")).unwrap_or_default()
        );
    }
    eprintln!(
        "replayed {dabs} dabs in {:.2} s (prefiltering included)",
        t0.elapsed().as_secs_f64()
    );
    if let Some(out) = &args.save {
        engine.save(out)?;
        eprintln!("saved {}", out.display());
    }
    if let (Some(rec), Some(p)) = (engine.recording(), &args.record) {
        rec.save(p)?;
    }
    // A run that ends normally leaves nothing to recover.
    engine.close_journal();
    Ok(())
}

/// The window journals edits in `--journal-dir DIR`, or by default in
/// [`ifd_brush::journal::default_dir`]; automated runs (`--replay`, `--save`,
/// `--screenshot`, `--exit`) only with `--journal-dir`, so that a test never
/// finds a recovery dialog in its way.
fn window_journal_dir(args: &Args) -> Option<PathBuf> {
    let automated =
        args.replay.is_some() || args.save.is_some() || args.screenshot.is_some() || args.exit;
    if args.no_journal {
        None
    } else if args.journal_dir.is_some() {
        args.journal_dir.clone()
    } else if automated {
        None
    } else {
        ifd_brush::journal::default_dir()
    }
}

fn window(args: &Args, budget: MemoryBudget) -> anyhow::Result<()> {
    let replay = args
        .replay
        .as_ref()
        .map(|p| StrokesFile::load(p))
        .transpose()?;
    let brush_override: Option<ifd_brush::BrushSettings> = args
        .brush
        .as_ref()
        .map(|j| serde_json::from_str(j))
        .transpose()
        .context("parsing --brush")?;
    // An automated run that fails leaves its message here and closes the
    // window; it is reported (exit 2) once the event loop has returned.
    let failure = std::sync::Arc::new(std::sync::Mutex::new(None::<String>));
    let start = StartOptions {
        image: args.image.clone(),
        bank_cache: args.bank.clone().or_else(Banks::default_cache),
        budget,
        gpu: args.device.into(),
        automation: Automation {
            replay,
            save: args.save.clone(),
            record: args.record.clone(),
            screenshot: args.screenshot.clone(),
            exit: args.exit,
            failure: std::sync::Arc::clone(&failure),
        },
        render_state: None,
        journal_dir: window_journal_dir(args),
    };
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("ifd brush")
            .with_inner_size([1280.0, 800.0])
            .with_drag_and_drop(true),
        // IFD_BRUSH_STATE_DIR keeps tests away from the user's settings.
        // (eframe takes the RON file's path here, whatever its docs say.)
        persistence_path: std::env::var_os("IFD_BRUSH_STATE_DIR")
            .map(|d| PathBuf::from(d).join("app.ron")),
        wgpu_options: ifd_app::wgpu_options(),
        ..eframe::NativeOptions::default()
    };
    eframe::run_native(
        "ifd-brush",
        options,
        Box::new(move |cc| {
            let mut start = start;
            // The window's device, shared with the GPU path (dabs painted
            // and shown there without a round trip).
            start.render_state = cc.wgpu_render_state.clone().map(WindowGpu);
            let mut settings: Persisted = cc
                .storage
                .and_then(|s| eframe::get_value(s, STORAGE_KEY))
                .unwrap_or_default();
            if let Some(b) = brush_override {
                settings.brush = b;
            }
            Ok(Box::new(Shell::new(
                BrushApp::new(&cc.egui_ctx, settings, start),
                STORAGE_KEY,
            )))
        }),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let failed = failure.lock().ok().and_then(|mut f| f.take());
    match failed {
        Some(msg) => Err(anyhow::anyhow!(msg)),
        None => Ok(()),
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    let budget = args
        .memory_budget
        .map_or_else(MemoryBudget::default_for_machine, |m| {
            MemoryBudget::bytes(m << 20)
        });
    let result =
        if args.exit && (args.replay.is_some() || args.recover) && args.screenshot.is_none() {
            headless(&args, budget)
        } else {
            window(&args, budget)
        };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory as _;

    /// `docs/reference/cli/ifd-brush.json` is what this binary defines, and its
    /// flags follow the grammar (the three binaries together are checked by
    /// `ifd-clidoc`'s tests, against the checked-in files).
    #[test]
    fn the_command_line_matches_its_checked_in_schema_and_the_grammar() {
        if let Err(e) = ifd_clidoc::check_binary(super::Args::command().name("ifd-brush")) {
            panic!("{e}");
        }
    }
}
