//! Replay and bad input, without a window.

mod common;
#[path = "../../../fuzz/harness_brush.rs"]
mod harness_brush;
#[path = "../../../tests/support/skip.rs"]
mod skip;

use std::process::Command;

use ifd_brush::engine::Engine;
use ifd_brush::stroke::dab_centres;
use ifd_brush::strokes::{Action, Stroke, StrokesFile};
use ifd_brush::{BrushMode, BrushSettings};
use ifd_image::{Image, MemoryBudget};
use ifd_smooth::{Dab, Smoother};

fn strokes() -> StrokesFile {
    let b1 = BrushSettings {
        radius: 20.0,
        strength: 0.8,
        falloff: 0.5,
        spacing: 0.3,
        mode: BrushMode::PerPixel,
        ..BrushSettings::default()
    };
    let b2 = BrushSettings {
        radius: 25.0,
        strength: 1.0,
        falloff: 0.3,
        mode: BrushMode::Dab,
        ..b1
    };
    StrokesFile {
        image_size: Some([200, 160]),
        strokes: vec![
            Action::Stroke(Stroke {
                brush: b1,
                points: vec![[30.0, 40.0], [120.0, 60.0], [150.0, 130.0]],
            }),
            Action::Stroke(Stroke {
                brush: b2,
                points: vec![[40.0, 120.0], [100.0, 30.0]],
            }),
            Action::Undo { undo: true },
            Action::Redo { redo: true },
            // Crosses both: reads the stack refreshed after stroke 2's redo.
            Action::Stroke(Stroke {
                brush: b1,
                points: vec![[20.0, 70.0], [180.0, 80.0]],
            }),
        ],
        ..StrokesFile::default()
    }
}

/// The library alone: the same dabs through `Smoother::apply_dab`, with a
/// smoother rebuilt from scratch after every stroke (`refresh: true`) or
/// never (`false`, to show the test sees the difference).
fn reference(img: &Image, file: &StrokesFile, refresh: bool) -> Image {
    let banks = common::banks();
    let mut img = img.clone();
    let mut done: Vec<&Stroke> = Vec::new();
    let mut undone: Vec<&Stroke> = Vec::new();
    // Undo/redo in this file are an undo then a redo of the same stroke.
    for a in &file.strokes {
        match a {
            Action::Stroke(s) => {
                done.push(s);
                undone.clear();
            }
            Action::Undo { .. } => undone.extend(done.pop()),
            Action::Redo { .. } => done.extend(undone.pop()),
        }
    }
    let mut sm: Option<Smoother> = None;
    for s in done {
        let opts = s.brush.smooth_options();
        if refresh || sm.is_none() {
            sm = Some(
                Smoother::with_banks(&img, &opts, banks.aspect.clone(), &banks.hessian)
                    .expect("smoother"),
            );
        }
        let smoother = sm.as_ref().expect("built");
        for (x, y) in dab_centres(&s.points, s.brush.spacing_px()) {
            let dab = Dab {
                x,
                y,
                radius: s.brush.radius,
                falloff: s.brush.falloff,
                strength: s.brush.strength,
            };
            smoother
                .apply_dab(&dab, s.brush.mode.into(), &mut img)
                .expect("dab");
        }
    }
    img
}

#[test]
fn headless_replay_equals_library_region_smoothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("in.png");
    let img = common::crop(150, 100, 200, 160);
    ifd_image::write(&input, &img).expect("write");
    // What the binary reads (8-bit quantised).
    let img = ifd_image::read(&input).expect("read");
    let file = strokes();
    let sfile = dir.path().join("strokes.json");
    file.save(&sfile).expect("save strokes");
    let out = dir.path().join("out.exr");
    let rec = dir.path().join("recorded.json");
    let status = Command::new(env!("CARGO_BIN_EXE_ifd-brush"))
        .arg(&input)
        .args(["--replay", sfile.to_str().expect("utf8")])
        .args(["--save", out.to_str().expect("utf8")])
        .args(["--record", rec.to_str().expect("utf8")])
        .args(["--bank", common::bank_cache().to_str().expect("utf8")])
        .arg("--exit")
        .status()
        .expect("run ifd-brush");
    assert!(status.success(), "ifd-brush failed: {status}");
    let got = ifd_image::read(&out).expect("result");
    // EXR stores grey as RGB.
    let got = Image::from_vec(got.width(), got.height(), 1, got.plane(0)).expect("grey");
    let want = reference(&img, &file, true);
    let stale = reference(&img, &file, false);
    let d = common::max_diff(&got, &want);
    let changed = common::max_diff(&img, &want);
    let stale_d = common::max_diff(&stale, &want);
    eprintln!(
        "replay vs library: max |diff| {d:.2e}; edit size {changed:.3}; without refresh {stale_d:.2e}"
    );
    assert!(
        changed > 0.05,
        "the strokes must change the image ({changed})"
    );
    assert!(stale_d > 1e-3, "refreshing must matter here ({stale_d})");
    assert!(d < 2e-4, "replay differs from the library by {d}");
    // --record wrote the same strokes back.
    let recorded = StrokesFile::load(&rec).expect("recording");
    assert_eq!(recorded.strokes, file.strokes);
}

#[test]
fn bad_inputs_leave_the_document_untouched() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut engine = Engine::new(common::banks(), MemoryBudget::bytes(64 << 20));
    let brush = BrushSettings::default();
    let good = dir.path().join("good.png");
    ifd_image::write(&good, &common::crop(0, 0, 96, 80)).expect("write");
    let l = engine.read(&good, &brush).expect("read");
    engine.set_image(l.image, Some(good.clone()), false);
    engine.begin_stroke(brush).expect("stroke");
    engine.stroke_to(40.0, 40.0).expect("dab");
    engine.end_stroke().expect("end");
    let edited = engine.image().expect("image").clone();
    assert_eq!(engine.history().undo_len(), 1);

    // Unreadable: missing, garbage, wrong extension.
    let garbage = dir.path().join("garbage.png");
    std::fs::write(&garbage, b"not a png").expect("write");
    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, b"text").expect("write");
    for p in [dir.path().join("missing.png"), garbage, notes] {
        let e = engine.read(&p, &brush).expect_err("must fail");
        let msg = format!("{e:#}");
        assert!(
            msg.contains(p.file_name().expect("name").to_str().expect("utf8")),
            "{msg}"
        );
    }
    // NaN pixels (EXR).
    let mut nan = common::crop(0, 0, 16, 16);
    nan.set(3, 4, 0, f32::NAN);
    let nan_path = dir.path().join("nan.exr");
    let fixture = ifd_image::WriteOptions {
        allow_non_finite: true,
        ..ifd_image::WriteOptions::default()
    };
    ifd_image::write_image(&nan_path, &nan, &fixture).expect("write exr");
    let msg = format!("{:#}", engine.read(&nan_path, &brush).expect_err("NaN"));
    assert!(
        msg.to_lowercase().contains("nan") || msg.contains("non-finite"),
        "{msg}"
    );
    // Beyond the 64 MiB budget: 3000x3000 RGB.
    let big = Image::new(3000, 3000, 3).expect("image");
    let msg = format!("{:#}", engine.check_fits(&big, &brush).expect_err("budget"));
    assert!(msg.contains("memory budget"), "{msg}");
    let big_path = dir.path().join("big.png");
    ifd_image::write(&big_path, &big).expect("write");
    assert!(engine.read(&big_path, &brush).is_err());

    // Nothing lost.
    assert_eq!(engine.image().expect("image").data(), edited.data());
    assert_eq!(engine.history().undo_len(), 1);
    engine.undo().expect("undo");
    assert_ne!(engine.image().expect("image").data(), edited.data());
}

/// The GPU path (`ifd-gpu`, here on whatever adapter exists, lavapipe
/// included) gives the CPU path's result for the same strokes. Without any
/// adapter this fails, unless `IFD_GPU_TESTS=skip` is set (as in
/// `crates/ifd-gpu/tests/gpu.rs`).
#[test]
fn gpu_replay_matches_cpu() {
    use ifd_gpu::DeviceChoice;
    let img = common::crop(150, 100, 200, 160);
    let file = strokes();
    let run = |choice: DeviceChoice| {
        let mut engine = Engine::new(common::banks(), MemoryBudget::default_for_machine());
        let (label, note) = engine.enable_gpu(choice);
        engine.set_image(img.clone(), None, false);
        engine.replay(&file).expect("replay");
        (engine.image().expect("image").clone(), label, note)
    };
    let (gpu, label, note) = run(DeviceChoice::Gpu);
    if !label.starts_with("GPU") {
        assert!(
            skip::allowed("IFD_GPU_TESTS"),
            "no GPU device for gpu_replay_matches_cpu ({}); install mesa-vulkan-drivers or set \
             IFD_GPU_TESTS=skip",
            note.as_deref().unwrap_or("no reason given")
        );
        skip::skip(&format!("no GPU device (IFD_GPU_TESTS=skip): {note:?}"));
        return;
    }
    let (cpu, cpu_label, _) = run(DeviceChoice::Cpu);
    assert_eq!(cpu_label, "CPU");
    let d = common::max_diff(&gpu, &cpu);
    let changed = common::max_diff(&img, &cpu);
    eprintln!("{label}: GPU vs CPU replay max |diff| {d:.2e} (edit size {changed:.3})");
    assert!(changed > 0.05);
    assert!(d < 1e-3, "GPU replay differs from CPU by {d}");

    // The display path: the document lives on a device shared with a
    // renderer (here one made by the test, as eframe's would be), dabs are
    // painted there without readback and the CPU copy catches up at the
    // end of each stroke; undo and redo write the CPU's pixels back, and
    // the last stroke paints over them.
    let ctx = ifd_gpu::GpuContext::new().expect("a device (the GPU path found one)");
    let shared = ifd_brush::engine::SharedDevice {
        device: ctx.device().clone(),
        queue: ctx.queue().clone(),
        info: ctx.adapter_info().clone(),
    };
    let mut engine = Engine::new(common::banks(), MemoryBudget::default_for_machine());
    let (shown, note) = engine.enable_gpu_on(DeviceChoice::Gpu, Some(shared));
    assert!(
        shown.ends_with("shown without readback"),
        "{shown} ({note:?})"
    );
    engine.set_image(img.clone(), None, false);
    let tiles = engine
        .display_tiles()
        .expect("display tiles on the shared device");
    assert_eq!(tiles.len(), 1);
    assert_eq!((tiles[0].0.width, tiles[0].0.height), (200, 160));
    engine.replay(&file).expect("replay");
    let on_device = engine.image().expect("image").clone();
    let d = common::max_diff(&on_device, &cpu);
    eprintln!("{shown}: GPU display path vs CPU replay max |diff| {d:.2e}");
    assert!(d < 1e-3, "GPU display path differs from CPU by {d}");
    // Strokes in progress are on the device only: the CPU copy follows at
    // the end. Then an undo (its pixels written to the device) and a stroke
    // over it, against the CPU path doing the same.
    let more = |engine: &mut Engine| {
        let before = engine.image().expect("image").clone();
        let brush = BrushSettings {
            radius: 30.0,
            strength: 1.0,
            ..BrushSettings::default()
        };
        engine.begin_stroke(brush).expect("stroke");
        engine.stroke_to(100.0, 80.0).expect("dab");
        engine.stroke_to(140.0, 90.0).expect("dab");
        let during = engine.image().expect("image").clone();
        assert!(engine.end_stroke().expect("end").is_some());
        assert!(common::max_diff(engine.image().expect("image"), &before) > 0.01);
        engine.undo().expect("undo");
        engine.begin_stroke(brush).expect("stroke");
        engine.stroke_to(120.0, 70.0).expect("dab");
        engine.stroke_to(90.0, 100.0).expect("dab");
        engine.end_stroke().expect("end");
        (
            during.data() == before.data(),
            engine.image().expect("image").clone(),
        )
    };
    let (stale_during, on_device) = more(&mut engine);
    assert!(
        stale_during,
        "the CPU copy changed during a stroke on the device"
    );
    let mut cpu_engine = Engine::new(common::banks(), MemoryBudget::default_for_machine());
    cpu_engine.set_image(img.clone(), None, false);
    cpu_engine.replay(&file).expect("replay");
    let (live_during, on_cpu) = more(&mut cpu_engine);
    assert!(!live_during, "the CPU path paints the CPU image at once");
    let d = common::max_diff(&on_device, &on_cpu);
    assert!(
        d < 1e-3,
        "GPU display path after undo differs from CPU by {d}"
    );
}

/// A device too small for the smoother's stack (1 MiB storage bindings) but
/// large enough for the document: dabs run on the CPU and are written to
/// the device, which still shows the document; the result is the CPU path's
/// and the status says why.
#[test]
fn gpu_display_paints_on_the_cpu_when_the_smoother_does_not_fit() {
    use eframe::wgpu;
    use ifd_brush::engine::SharedDevice;
    use ifd_gpu::DeviceChoice;
    let Ok(big) = ifd_gpu::GpuContext::new() else {
        assert!(
            skip::allowed("IFD_GPU_TESTS"),
            "no GPU device for this test; install mesa-vulkan-drivers or set IFD_GPU_TESTS=skip"
        );
        skip::skip("no GPU device (IFD_GPU_TESTS=skip)");
        return;
    };
    let shared = pollster::block_on(async {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let adapter = instance
            .enumerate_adapters(wgpu::Backends::all())
            .await
            .into_iter()
            .find(|a| a.get_info().name == big.adapter_info().name)
            .expect("the same adapter again");
        let info = adapter.get_info();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("small limits"),
                required_limits: wgpu::Limits {
                    max_storage_buffer_binding_size: 1 << 20,
                    max_buffer_size: 2 << 20,
                    ..wgpu::Limits::default()
                },
                ..wgpu::DeviceDescriptor::default()
            })
            .await
            .expect("device with small limits");
        SharedDevice {
            device,
            queue,
            info,
        }
    });
    let img = common::crop(150, 100, 200, 160);
    let file = strokes();
    let mut engine = Engine::new(common::banks(), MemoryBudget::default_for_machine());
    engine.enable_gpu_on(DeviceChoice::Gpu, Some(shared));
    engine.set_image(img.clone(), None, false);
    assert!(
        engine.displays_on_device(),
        "a 200x160 document fits in 1 MiB"
    );
    engine.replay(&file).expect("replay");
    let (label, note) = engine.compute();
    assert_eq!(label, "CPU, shown from the GPU");
    let note = note.expect("a reason");
    assert!(note.contains("the device's max_"), "{note}");
    let mut cpu = Engine::new(common::banks(), MemoryBudget::default_for_machine());
    cpu.set_image(img.clone(), None, false);
    cpu.replay(&file).expect("replay");
    let d = common::max_diff(engine.image().expect("image"), cpu.image().expect("image"));
    assert!(
        d < 1e-6,
        "CPU dabs shown from the GPU differ from the CPU path by {d}"
    );
}

/// A stroke out to a point absurdly far from the image and back paints the
/// dabs near the image only (it used to generate every dab along the way:
/// billions, and run out of memory).
#[test]
fn far_stroke_points_cost_only_the_dabs_near_the_image() {
    let img = common::crop(150, 100, 200, 160);
    let mut engine = Engine::new(common::banks(), MemoryBudget::default_for_machine());
    engine.set_image(img.clone(), None, false);
    let brush = BrushSettings {
        radius: 20.0,
        ..BrushSettings::default()
    };
    engine.begin_stroke(brush).expect("stroke");
    let mut dabs = engine.stroke_to(10.0, 10.0).expect("dab").times.len();
    dabs += engine.stroke_to(1e9, 1e9).expect("far").times.len();
    dabs += engine.stroke_to(30.0, 150.0).expect("back").times.len();
    engine.end_stroke().expect("end");
    assert!(dabs > 2 && dabs < 200, "{dabs} dabs");
    assert!(common::max_diff(engine.image().expect("image"), &img) > 0.01);
}

/// The strokes fuzz target's corpus (`fuzz/seeds/strokes/`, and
/// `fuzz/regressions/strokes/`: inputs that once failed) goes through the
/// fuzz harness without a panic (`tests/fuzz_corpus.rs` replays the other
/// targets).
#[test]
fn strokes_fuzz_corpus_replays_without_panics() {
    let fuzz = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz");
    let mut n = 0;
    for kind in ["seeds", "regressions"] {
        let Ok(dir) = std::fs::read_dir(fuzz.join(kind).join("strokes")) else {
            assert_ne!(kind, "seeds", "fuzz/seeds/strokes/ is missing");
            continue;
        };
        let mut files: Vec<_> = dir.filter_map(|e| e.ok().map(|e| e.path())).collect();
        files.sort();
        for path in files {
            let data = std::fs::read(&path).expect("corpus file");
            let r = std::panic::catch_unwind(|| harness_brush::strokes(&data));
            assert!(r.is_ok(), "{} panics the strokes harness", path.display());
            n += 1;
        }
    }
    assert!(n >= 2, "only {n} strokes corpus inputs");
}

/// Edits are saved as they are painted (`ifd_brush::journal`): a headless
/// replay killed (SIGKILL) after it reports its third saved journal entry
/// is recovered by the next start on the same image, and the recovered image
/// equals the library's replay of the entries the journal kept, which are
/// at least the three reported and fewer than the whole replay (the kill
/// interrupted it). A run that ends normally deletes its journal.
#[test]
fn killed_replay_is_recovered_from_the_journal() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("in.png");
    ifd_image::write(&input, &common::crop(150, 100, 200, 160)).expect("write");
    let journal_dir = dir.path().join("journal");
    let brush = BrushSettings {
        radius: 18.0,
        strength: 0.8,
        mode: BrushMode::Dab,
        ..BrushSettings::default()
    };
    let total = 8;
    let file = StrokesFile {
        image_size: Some([200, 160]),
        strokes: (0..total)
            .map(|k| {
                let y = 15.0 + 18.0 * k as f32;
                Action::Stroke(Stroke {
                    brush,
                    points: vec![[10.0, y], [190.0, 160.0 - y]],
                })
            })
            .collect(),
        ..StrokesFile::default()
    };
    let sfile = dir.path().join("strokes.json");
    file.save(&sfile).expect("save strokes");
    let bank = common::bank_cache();
    let arg = |p: &std::path::Path| p.to_str().expect("utf8").to_string();
    let mut child = Command::new(env!("CARGO_BIN_EXE_ifd-brush"))
        .args([&arg(&input), "--replay", &arg(&sfile)])
        .args(["--journal-dir", &arg(&journal_dir), "--bank", &arg(&bank)])
        .args(["--device", "cpu", "--replay-pace", "400", "--exit"])
        .stderr(Stdio::piped())
        .spawn()
        .expect("run ifd-brush");
    let stderr = child.stderr.take().expect("stderr");
    let mut seen = Vec::new();
    for line in BufReader::new(stderr).lines() {
        let line = line.expect("stderr line");
        let third = line.starts_with("journal: saved entry 3 ");
        seen.push(line);
        if third {
            break;
        }
    }
    child.kill().expect("kill");
    child.wait().expect("wait");
    assert!(
        seen.iter()
            .any(|l| l.starts_with("journal: saved entry 3 ")),
        "the replay never reported a third saved entry:\n{}",
        seen.join("\n")
    );
    let journals: Vec<_> = std::fs::read_dir(&journal_dir)
        .expect("journal folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    assert_eq!(journals.len(), 1, "{journals:?}");
    let kept = ifd_brush::journal::read(&journals[0]).expect("journal");
    let n = kept.strokes.strokes.len();
    assert!(
        (3..total).contains(&n),
        "the journal kept {n} of {total} strokes; the kill came after the 3rd was saved and before the end"
    );
    assert_eq!(kept.strokes.strokes[..], file.strokes[..n]);

    // The next start on the image recovers the journal.
    let out = dir.path().join("recovered.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_ifd-brush"))
        .args([&arg(&input), "--journal-dir", &arg(&journal_dir)])
        .args(["--bank", &arg(&bank), "--device", "cpu", "--recover"])
        .args(["--save", &arg(&out), "--exit"])
        .output()
        .expect("run ifd-brush --recover");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(&format!("recovered {n} journal entries")),
        "{err}"
    );
    let got = ifd_image::read(&out).expect("recovered image");
    let got = Image::from_vec(got.width(), got.height(), 1, got.plane(0)).expect("grey");

    // The library, without a journal: the same entries on the same pixels.
    let mut engine = Engine::new(common::banks(), MemoryBudget::default_for_machine());
    let loaded = engine.read(&input, &brush).expect("read");
    let original = loaded.image.clone();
    engine.set_image(loaded.image, None, false);
    engine.replay(&kept.strokes).expect("replay");
    let want = engine.image().expect("image").clone();
    let d = common::max_diff(&got, &want);
    let changed = common::max_diff(&original, &want);
    eprintln!(
        "recovered {n} of {total} strokes; max |recovered - replay| {d:.2e} (edit size {changed:.3})"
    );
    assert!(
        changed > 0.05,
        "the strokes must change the image ({changed})"
    );
    assert!(
        d <= 1e-6,
        "the recovered image differs from the replay by {d}"
    );
    // That run ended normally: its journal is gone.
    let left: Vec<_> = std::fs::read_dir(&journal_dir)
        .expect("journal folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
