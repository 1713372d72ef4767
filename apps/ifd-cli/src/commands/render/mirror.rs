//! The work of `ifd render --brdf mirror`, its flags checked: the surface
//! as a perfect mirror, anti-aliased by ISD's filter (Eq. 26-29) or by
//! supersampling the pixel filter; the outputs and the report.

use std::fmt::Write as _;

use anyhow::{Result, bail};
use ifd_render::{AaMethod, IsdFilter, MirrorScene, PixelFilter, SceneMirror};
use serde_json::json;

use super::Render;
use super::config::{MirrorConfig, View};

impl Render {
    /// Renders the scene as a mirror, writes the outputs and the report.
    pub(super) fn render_mirror(&self, view: View, c: MirrorConfig) -> Result<()> {
        let View {
            scene,
            camera,
            tonemap,
            display,
        } = view;
        let MirrorConfig { method, l_max } = c;
        let maps = self.surface_maps()?;
        let (full, _) = self.env.environments(&self.input)?;
        let start = std::time::Instant::now();
        let isd = match (method, l_max) {
            (AaMethod::Isd, Some(l)) => {
                eprintln!("projecting the map on SH up to L = {l}...");
                Some(IsdFilter::new(&full, l)?)
            }
            _ => None,
        };
        let reflector = SceneMirror {
            scene: &scene,
            normal_map: maps.normal.as_ref(),
        };
        let job = MirrorScene {
            mirror: &reflector,
            camera,
            env: &full,
            filter: PixelFilter::default(),
        };
        let t_render = std::time::Instant::now();
        let r = ifd_render::render_mirror(&job, method, isd.as_ref())?;
        let render_secs = t_render.elapsed().as_secs_f64();
        let object_pixels = r.mask.iter().filter(|m| **m).count();
        if object_pixels == 0 {
            bail!(
                "no ray of the {}x{} image hits the {} (check --eye, --target, --fov)",
                camera.width(),
                camera.height(),
                self.scene.scene
            );
        }
        let mut img = r.image;
        let ch = img.channels();
        if self.no_background {
            for (i, m) in r.mask.iter().enumerate() {
                if !m {
                    img.data_mut()[i * ch..(i + 1) * ch].fill(0.0);
                }
            }
        }
        if display {
            for v in img.data_mut() {
                *v = tonemap.display(*v, self.display.exposure);
            }
        }
        if let Some(m) = &self.mask {
            let data = r.mask.iter().map(|x| f32::from(u8::from(*x))).collect();
            let mask = ifd_image::Image::from_vec(camera.width(), camera.height(), 1, data)?;
            crate::output::write_output(m, &mask, &ifd_image::WriteOptions::default())?;
        }
        crate::output::write_output(&self.output, &img, &ifd_image::WriteOptions::default())?;
        let secs = start.elapsed().as_secs_f64();
        let summary = || {
            let spp = match method {
                AaMethod::Isd => None,
                _ => Some(self.spp),
            };
            let mut text = self.summary_head(
                (camera.width(), camera.height()),
                l_max,
                "mirror",
                spp,
                secs,
            );
            if isd.is_some() {
                let _ = writeln!(
                    text,
                    "Eq. 29 filtered {} of the {object_pixels} object pixels",
                    r.filtered
                );
            }
            text
        };
        let report = json!({
            "method": self.method.name(), "brdf": "mirror", "lmax": l_max,
            "scene": self.scene.scene, "width": camera.width(), "height": camera.height(),
            "env_size": [full.image().width(), full.image().height()],
            "object_pixels": object_pixels,
            "eq29_pixels": isd.as_ref().map(|_| r.filtered),
            "isd_threshold_radians": isd.as_ref().map(IsdFilter::threshold),
            "samples_per_pixel": match method { AaMethod::Isd => None, _ => Some(self.spp) },
            "seconds": secs, "render_seconds": render_secs,
        });
        self.report.emit_summary(&report, summary)?;
        Ok(())
    }
}
