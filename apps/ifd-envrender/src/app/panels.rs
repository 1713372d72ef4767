//! The side panel (settings), the status bar, and the viewport with the
//! orbit camera's controls.

use egui::{Color32, Sense, Stroke, vec2};

use super::EnvApp;
use crate::settings::{Compare, Variant};

/// The BRDF models the panel offers.
const MODELS: [&str; 6] = ["lambert", "phong", "blinn", "blinn-exact", "ggx", "ward"];

/// A parameter's slider: range and whether it is logarithmic.
fn range_of(key: &str) -> (f64, f64, bool) {
    match key {
        "s" => (1.0, 5000.0, true),
        "alpha" | "ax" | "ay" => (0.01, 1.0, true),
        _ => (0.0, 1.0, false), // albedo, f0
    }
}

/// A spec's model and its numeric parameters, if the panel can edit it
/// (not `merl:FILE`).
fn parse_spec(spec: &str) -> Option<(String, Vec<(String, f64)>)> {
    let (model, params) = spec.split_once(':').unwrap_or((spec, ""));
    if !MODELS.contains(&model) {
        return None;
    }
    let mut out = Vec::new();
    for kv in params.split(',').filter(|t| !t.trim().is_empty()) {
        let (k, v) = kv.split_once('=')?;
        out.push((k.trim().to_string(), v.trim().parse().ok()?));
    }
    Some((model.to_string(), out))
}

/// The spec of a model and its parameters.
fn spec_of(model: &str, params: &[(String, f64)]) -> String {
    if params.is_empty() {
        return model.to_string();
    }
    let p: Vec<String> = params
        .iter()
        .map(|(k, v)| {
            if k == "s" {
                format!("{k}={}", v.round())
            } else {
                format!("{k}={v:.3}")
            }
        })
        .collect();
    format!("{model}:{}", p.join(","))
}

/// The parameters a model starts with.
fn defaults_of(model: &str) -> Vec<(String, f64)> {
    let p: &[(&str, f64)] = match model {
        "phong" | "blinn" | "blinn-exact" => &[("s", 32.0)],
        "ggx" | "ward" => &[("alpha", 0.3)],
        _ => &[],
    };
    p.iter().map(|(k, v)| ((*k).to_string(), *v)).collect()
}

/// The BRDF editor: model, a slider per parameter, the anisotropic and
/// Fresnel switches; any other spec (MERL) is edited as text only.
fn brdf_editor(ui: &mut egui::Ui, spec: &mut String) {
    let Some((model, mut params)) = parse_spec(spec) else {
        return;
    };
    let mut m = model.clone();
    egui::ComboBox::from_id_salt("model")
        .selected_text(m.clone())
        .show_ui(ui, |ui| {
            for name in MODELS {
                ui.selectable_value(&mut m, name.to_string(), name);
            }
        });
    let mut changed = m != model;
    if changed {
        params = defaults_of(&m);
    }
    let has = |p: &[(String, f64)], k: &str| p.iter().any(|(q, _)| q == k);
    if m == "ggx" || m == "ward" {
        let mut aniso = has(&params, "ax");
        if ui.checkbox(&mut aniso, "anisotropic").changed() {
            changed = true;
            let a = params
                .iter()
                .find(|(k, _)| k == "alpha" || k == "ax")
                .map_or(0.3, |p| p.1);
            params.retain(|(k, _)| !matches!(k.as_str(), "alpha" | "ax" | "ay"));
            if aniso {
                params.insert(0, ("ay".into(), a));
                params.insert(0, ("ax".into(), a));
            } else {
                params.insert(0, ("alpha".into(), a));
            }
        }
    }
    if m == "ggx" {
        let mut fresnel = has(&params, "f0");
        if ui.checkbox(&mut fresnel, "Fresnel (f0)").changed() {
            changed = true;
            if fresnel {
                params.push(("f0".into(), 0.04));
            } else {
                params.retain(|(k, _)| k != "f0");
            }
        }
    }
    let mut albedo = params
        .iter()
        .find(|(k, _)| k == "albedo")
        .map_or(1.0, |p| p.1);
    for (k, v) in params.iter_mut().filter(|(k, _)| k != "albedo") {
        let (lo, hi, log) = range_of(k);
        changed |= ui
            .add(
                egui::Slider::new(v, lo..=hi)
                    .logarithmic(log)
                    .text(k.as_str()),
            )
            .changed();
    }
    changed |= ui
        .add(egui::Slider::new(&mut albedo, 0.0..=1.0).text("albedo"))
        .changed();
    params.retain(|(k, _)| k != "albedo");
    if (albedo - 1.0).abs() > 1e-9 {
        params.push(("albedo".into(), albedo));
    }
    if changed {
        *spec = spec_of(&m, &params);
    }
}

pub(super) fn side_panel(app: &mut EnvApp, ui: &mut egui::Ui) {
    egui::Panel::left("settings")
        .resizable(false)
        .default_size(250.0)
        .show(ui, |ui| {
            let s = &mut app.settings;
            ui.heading("Environment");
            let name = s.env.as_ref().and_then(|p| p.file_name()).map_or_else(
                || "bundled forest.hdr".into(),
                |n| n.to_string_lossy().into_owned(),
            );
            ui.label(name)
                .on_hover_text("drop an HDR/EXR map on the window to open it");
            ui.add(egui::Slider::new(&mut s.env_rotate, -180.0..=180.0).text("rotation (deg)"));
            ui.checkbox(&mut s.background, "background");
            ui.separator();
            ui.heading("Scene");
            let shown = std::path::Path::new(&s.scene)
                .file_name()
                .map_or_else(|| s.scene.clone(), |n| n.to_string_lossy().into_owned());
            egui::ComboBox::from_id_salt("scene")
                .selected_text(shown)
                .show_ui(ui, |ui| {
                    for name in ["sphere", "torus", "plane"] {
                        ui.selectable_value(&mut s.scene, name.to_string(), name);
                    }
                })
                .response
                .on_hover_text("drop an .obj, .gltf or .glb file on the window to open it");
            if s.scene_is_gltf() && s.brdf == "gltf" {
                ui.label("shaded with the asset's own materials");
            }
            ui.separator();
            ui.heading("BRDF");
            brdf_editor(ui, &mut s.brdf);
            for (what, slot) in [
                ("albedo map", &mut s.albedo_map),
                ("roughness map", &mut s.roughness_map),
            ] {
                if let Some(p) = slot.clone() {
                    ui.horizontal(|ui| {
                        let name = p
                            .file_name()
                            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                        ui.label(format!("{what}: {name}"));
                        if ui.small_button("clear").clicked() {
                            *slot = None;
                        }
                    });
                }
            }
            ui.horizontal(|ui| {
                ui.label("spec");
                ui.text_edit_singleline(&mut s.brdf).on_hover_text(
                    "any `ifd render --brdf` spec, e.g. merl:FILE or ggx:ax=0.1,ay=0.4",
                );
            });
            ui.separator();
            ui.heading("Shading");
            ui.add(egui::Slider::new(&mut s.l_max, 1..=63).text("L (max SH degree)"));
            ui.horizontal(|ui| {
                ui.radio_value(&mut s.variant, Variant::Sh, "SH");
                ui.radio_value(&mut s.variant, Variant::Maps, "per-band maps");
            });
            ui.separator();
            ui.heading("Display");
            ui.add(egui::Slider::new(&mut s.exposure, -6.0..=6.0).text("exposure (EV)"));
            egui::ComboBox::from_id_salt("tonemap")
                .selected_text(s.tonemap.clone())
                .show_ui(ui, |ui| {
                    for name in ["aces", "reinhard", "none"] {
                        ui.selectable_value(&mut s.tonemap, name.to_string(), name);
                    }
                });
            ui.label("drag: orbit, wheel: zoom, F: frame");
            ui.separator();
            ui.heading("Reference");
            let was = s.reference;
            ui.checkbox(&mut s.reference, "Monte Carlo reference, side by side")
                .on_hover_text(
                    "refined on a worker thread while the camera is still (8 samples per pixel \
                     a pass, up to 1024); ISD's error against it below",
                );
            if s.reference && !was {
                // one view beside ISD's at a time
                s.compare = Compare::Off;
            }
            if s.reference {
                reference_report(ui, &app.refs, s.l_max);
            }
            ui.separator();
            ui.heading("Split sum");
            split_sum_panel(ui, s, &app.split);
            ui.separator();
            ui.heading("Frame times");
            frame_plot(ui, &app.ui_times);
            if let Some(g) = &app.gpu
                && let Some(last) = g.gpu_frames.last()
            {
                ui.label(format!(
                    "GPU shading per frame (timestamps): {last:.1} ms, {} frames",
                    g.gpu_frames.len()
                ));
                gpu_plot(ui, &g.gpu_frames);
            }
        });
}

/// The split-sum comparison: which engine's, image or difference, the
/// colour scale.
fn split_sum_panel(
    ui: &mut egui::Ui,
    s: &mut crate::settings::Settings,
    split: &super::SplitState,
) {
    if !s.brdf_is_gltf() {
        ui.label("for the glTF BRDF: gltf:roughness=..,metallic=.. or a .gltf/.glb asset");
        return;
    }
    let was = s.compare;
    ui.radio_value(&mut s.compare, Compare::Off, "off");
    ui.radio_value(
        &mut s.compare,
        Compare::SplitSum,
        "split sum (ISD's BRDF split)",
    )
    .on_hover_text(
        "the prefiltered chain, irradiance and DFG table of `ifd envmap prefilter`, with \
             the same Fresnel-weighted diffuse as ISD: the approximation's own error",
    );
    ui.radio_value(
        &mut s.compare,
        Compare::SampleRenderer,
        "split sum (glTF-Sample-Renderer's shader)",
    )
    .on_hover_text("pbr.frag and ibl.glsl as written, with their multiple-scattering term");
    if s.compare != was && s.compare != Compare::Off {
        s.reference = false;
    }
    if s.compare == Compare::Off {
        return;
    }
    ui.checkbox(&mut s.compare_image, "show the split-sum image")
        .on_hover_text("else its difference from ISD's image");
    match &split.difference {
        Some(d) if !s.compare_image => {
            ui.label(format!(
                "(split sum - ISD) / ISD: blue darker, red brighter, full scale +/-{:.1}% (95% of \
                 the object's pixels)",
                100.0 * d.full_scale
            ));
        }
        Some(_) => {}
        None => {
            ui.label("waiting for the frame and the split sum");
        }
    }
}

/// GPU time per shaded frame (ms), scaled to the largest.
fn gpu_plot(ui: &mut egui::Ui, times: &[f32]) {
    let (rect, _) = ui.allocate_exact_size(vec2(220.0, 40.0), Sense::hover());
    let p = ui.painter_at(rect);
    p.rect_filled(rect, 2.0, Color32::from_gray(24));
    let top = times.iter().copied().fold(1e-3f32, f32::max);
    let n = times.len().max(2);
    let pts: Vec<egui::Pos2> = times
        .iter()
        .enumerate()
        .map(|(i, t)| {
            egui::pos2(
                rect.left() + rect.width() * i as f32 / (n - 1) as f32,
                rect.bottom() - (t / top) * (rect.height() - 4.0),
            )
        })
        .collect();
    p.add(egui::Shape::line(pts, Stroke::new(1.0, Color32::GOLD)));
    p.text(
        rect.left_top() + vec2(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        format!("{top:.0} ms"),
        egui::FontId::monospace(9.0),
        Color32::GRAY,
    );
}

/// The reference's progress, ISD's error against it, and the error over `L`.
fn reference_report(ui: &mut egui::Ui, r: &super::RefState, l_max: usize) {
    match (&r.image, r.error) {
        (Some((_, _, spp)), Some((rel, psnr))) => {
            ui.label(format!(
                "{spp} spp: ISD rel. RMS {rel:.4}, PSNR {psnr:.1} dB"
            ));
        }
        (Some((_, _, spp)), None) => {
            ui.label(format!("{spp} spp"));
        }
        _ => {
            ui.label("waiting for a still camera");
        }
    }
    let Some((points, spp)) = &r.curve else {
        return;
    };
    if points.is_empty() {
        ui.label(
            "no error-against-L curve: a roughness map or a glTF asset's materials need a table \
             family at every degree",
        );
        return;
    }
    ui.label(format!("error against L (reference at {spp} spp):"));
    let (rect, _) = ui.allocate_exact_size(vec2(220.0, 80.0), Sense::hover());
    let p = ui.painter_at(rect);
    p.rect_filled(rect, 2.0, Color32::from_gray(24));
    let logs: Vec<f64> = points.iter().map(|(_, e)| e.max(1e-6).log10()).collect();
    let (lo, hi) = logs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let (lo, hi) = (lo.floor(), hi.ceil().max(lo.floor() + 1.0));
    let lmax = points.iter().map(|(l, _)| *l).max().unwrap_or(1).max(1) as f32;
    let at = |l: usize, v: f64| {
        egui::pos2(
            rect.left() + 4.0 + (rect.width() - 8.0) * l as f32 / lmax,
            rect.bottom() - 4.0 - (rect.height() - 8.0) * ((v - lo) / (hi - lo)) as f32,
        )
    };
    let pts: Vec<egui::Pos2> = points
        .iter()
        .zip(&logs)
        .map(|((l, _), v)| at(*l, *v))
        .collect();
    for q in &pts {
        p.circle_filled(*q, 2.0, Color32::LIGHT_BLUE);
    }
    p.add(egui::Shape::line(
        pts,
        Stroke::new(1.0, Color32::LIGHT_BLUE),
    ));
    p.text(
        rect.left_top() + vec2(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        format!("1e{hi:.0}"),
        egui::FontId::monospace(9.0),
        Color32::GRAY,
    );
    p.text(
        rect.left_bottom() + vec2(4.0, -2.0),
        egui::Align2::LEFT_BOTTOM,
        format!("1e{lo:.0}"),
        egui::FontId::monospace(9.0),
        Color32::GRAY,
    );
    if let Some((_, e)) = points.iter().find(|(l, _)| *l == l_max) {
        ui.label(format!(
            "at L = {l_max}: {e:.4} (floor: the reference's noise)"
        ));
    }
}

/// UI frame times (ms) as a small line plot with the 50 ms line.
fn frame_plot(ui: &mut egui::Ui, times: &[f32]) {
    let (rect, _) = ui.allocate_exact_size(vec2(220.0, 60.0), Sense::hover());
    let p = ui.painter_at(rect);
    p.rect_filled(rect, 2.0, Color32::from_gray(24));
    let top = 100.0f32;
    let y = |ms: f32| rect.bottom() - (ms.min(top) / top) * rect.height();
    p.hline(rect.x_range(), y(50.0), Stroke::new(1.0, Color32::DARK_RED));
    let n = times.len().max(2);
    let pts: Vec<egui::Pos2> = times
        .iter()
        .enumerate()
        .map(|(i, t)| {
            egui::pos2(
                rect.left() + rect.width() * i as f32 / (n - 1) as f32,
                y(*t),
            )
        })
        .collect();
    p.add(egui::Shape::line(
        pts,
        Stroke::new(1.0, Color32::LIGHT_GREEN),
    ));
    let last = times.last().copied().unwrap_or(0.0);
    ui.label(format!("UI frame {last:.1} ms (red: 50 ms)"));
}

pub(super) fn status_bar(app: &mut EnvApp, ui: &mut egui::Ui) {
    egui::Panel::bottom("status").show(ui, |ui| {
        ui.horizontal_wrapped(|ui| {
            match (&app.cpu_reason, &app.fallback) {
                (None, None) => ui.label(format!("GPU: {}", app.adapter)),
                (None, Some(why)) => ui.colored_label(
                    Color32::YELLOW,
                    format!("CPU shading for this frame: the GPU cannot ({why})"),
                ),
                (Some(why), _) => {
                    ui.label(format!("CPU shading ({why}); adapter: {}", app.adapter))
                }
            };
            ui.separator();
            let i = &app.info;
            ui.label(format!("{} | {} | {} lobes/pixel", i.env, i.brdf, i.lobes));
            let table = i
                .table_bytes
                .map_or_else(|| "closed form".into(), |b| ifd_image::fmt_bytes(b as u64));
            ui.label(format!(
                "table {table} | environment {}",
                ifd_image::fmt_bytes(i.env_bytes as u64)
            ));
            let shade = app
                .gpu
                .as_ref()
                .and_then(|g| g.last_frame)
                .or(app.cpu_frame);
            if let Some(t) = shade {
                ui.label(format!("frame {:.0} ms", t.as_secs_f64() * 1e3));
            }
            if app.settings.compare != Compare::Off
                && let Some(d) = &app.split.difference
            {
                ui.separator();
                ui.label(format!(
                    "split sum vs ISD (L = {}): relative RMS {:.2}%, PSNR {:.1} dB, 95% within \
                     {:.1}%, largest {:.3}",
                    app.settings.l_max,
                    100.0 * d.relative_rms,
                    d.psnr_db,
                    100.0 * d.full_scale,
                    d.max_abs
                ))
                .on_hover_text(
                    "over the object's pixels, ISD's image as the reference (its own error \
                     against the exact integral falls with L: see the Monte Carlo reference)",
                );
                if let Some(t) = app.split.seconds {
                    ui.label(format!("split sum {:.0} ms", t * 1e3));
                }
            }
            if !app.progress.is_empty() {
                ui.spinner();
                ui.label(&app.progress);
            }
            if let Some(e) = app.errors.last() {
                ui.colored_label(Color32::LIGHT_RED, e);
            }
        });
    });
}

pub(super) fn viewport(app: &mut EnvApp, ui: &mut egui::Ui) {
    egui::CentralPanel::default().show(ui, |ui| {
        let tex = match &app.gpu {
            Some(g) if app.fallback.is_none() => g.texture(),
            _ => app.cpu_texture.as_ref().map(|t| (t.id(), t.size())),
        };
        let ppp = ui.ctx().pixels_per_point();
        // the view beside ISD's, when one is asked for: its place is kept
        // while it is computed, so that ISD's view does not jump
        let second = if app.settings.reference {
            Some(("reference", app.refs.texture.as_ref()))
        } else if app.settings.compare != Compare::Off && app.settings.brdf_is_gltf() {
            // (the worker compares the glTF BRDF only)
            let t = if app.split.image.is_none() {
                None
            } else if app.settings.compare_image {
                app.split.texture.as_ref()
            } else {
                app.split
                    .difference
                    .as_ref()
                    .and(app.split.difference_texture.as_ref())
            };
            let name = if app.settings.compare_image {
                "split-sum"
            } else {
                "split-sum-difference"
            };
            Some((name, t))
        } else {
            None
        };
        // the views whole inside the area: pixel for pixel when they fit,
        // else scaled down (the texture is rendered at --size and shown
        // scaled), side by side or stacked
        let area = ui.available_rect_before_wrap();
        let count = 1 + usize::from(second.is_some());
        let rects = ifd_app::fit_views(area, app.settings.size, count, 8.0, ppp);
        let rect = rects[0];
        let resp = ui.allocate_rect(rect, Sense::click_and_drag());
        let whole = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        if let Some((id, _)) = tex {
            ui.painter().image(id, rect, whole, Color32::WHITE);
        } else {
            ui.painter().rect_filled(rect, 0.0, Color32::from_gray(16));
        }
        let mut views = vec![("isd", rect)];
        if let (Some((name, t)), Some(r)) = (second, rects.get(1).copied()) {
            if let Some(t) = t {
                ui.painter().image(t.id(), r, whole, Color32::WHITE);
            } else {
                ui.painter().rect_filled(r, 0.0, Color32::from_gray(16));
            }
            views.push((name, r));
        }
        app.layout = Some(super::Layout { area, views });
        let cam = &mut app.settings.camera;
        if resp.dragged() {
            let d = resp.drag_delta();
            cam.drag(f64::from(d.x), f64::from(d.y));
        }
        if resp.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                cam.zoom(f64::from(scroll));
            }
        }
        if ui.input(|i| i.key_pressed(egui::Key::F)) {
            let r = match app.settings.scene.as_str() {
                "torus" => 1.4,
                "plane" => 2.0 * std::f64::consts::SQRT_2,
                _ => 1.0,
            };
            cam.frame(r);
        }
        if let Some(p) = super::dropped_path(ui.ctx()) {
            let scene = p.extension().is_some_and(|e| {
                ["obj", "gltf", "glb"]
                    .iter()
                    .any(|x| e.eq_ignore_ascii_case(x))
            });
            if scene {
                app.settings.open_scene(&p);
            } else {
                app.settings.env = Some(p);
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn editor_specs_round_trip_and_parse() {
        for spec in [
            "lambert",
            "phong:s=32",
            "blinn-exact:s=100,albedo=0.5",
            "ggx:ax=0.1,ay=0.4,f0=0.04",
            "ward:alpha=0.3",
        ] {
            let (m, p) = parse_spec(spec).expect("editable");
            let again = spec_of(&m, &p);
            assert_eq!(parse_spec(&again), Some((m.clone(), p)), "{spec}");
            ifd_shade::Brdf::parse(&again).expect("a valid spec");
            // every model's defaults are a valid spec
            ifd_shade::Brdf::parse(&spec_of(&m, &defaults_of(&m))).expect("defaults");
        }
        assert!(parse_spec("merl:alum.binary").is_none());
        assert!(parse_spec("ggx:alpha=x").is_none());
    }
}
