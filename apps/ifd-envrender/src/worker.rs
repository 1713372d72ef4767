//! Everything slow runs here, on its own thread: reading the environment map,
//! its SH projection and per-band maps, lobe tables, the G-buffer, the
//! uploads, and (without the GPU path) the CPU render. The UI sends the
//! whole [`Settings`] whenever they change; the worker works on the latest
//! only, reuses what did not change, and answers with [`Event`]s. A step
//! that fails reports an error and keeps the previous scene.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender};
use std::time::Instant;

use anyhow::{Context, Result};
use ifd_gpu::GpuContext;
use ifd_gpu::{GpuEnvironment, GpuMaterial, GpuShader, GpuSurfaces, SurfacePoint};
use ifd_render::EnvMap;
use ifd_render::Scene;
use ifd_render::Tonemap;
use ifd_render::{Job, Method, render};
use ifd_render::{RoughnessFamily, SplitSum, SurfaceMaps, Texture};
use ifd_shade::Brdf;
use ifd_shade::{BandMaps, Environment, Material, Precision};
use ifd_shade::{LobeTable, default_theta_entries};

use crate::settings::{Compare, Settings, Variant, bundled_env};

/// What the worker tells the UI.
#[derive(Debug)]
pub enum Event {
    /// Work in progress (shown in the status bar).
    Progress(String),
    /// A step failed; the previous scene stays.
    Error(String),
    /// The GPU cannot shade these settings (a device limit); this frame was
    /// rendered on the CPU.
    Fallback(String),
    /// The scene's description, after each change.
    Info(Info),
    /// A frame to show.
    Frame(Frame),
    /// The split-sum image of the last frame ([`Settings::compare`]), linear
    /// radiance, with its object mask.
    SplitSum {
        /// The image.
        image: Arc<ifd_image::Image>,
        /// Object pixels, row-major.
        mask: Arc<Vec<bool>>,
        /// Bake (when the map changed) and render time, seconds.
        seconds: f64,
    },
}

/// The current scene, for the status bar.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Info {
    /// The map's file name and its size.
    pub env: String,
    /// The BRDF spec.
    pub brdf: String,
    /// Lobe table bytes (`None`: closed-form weights).
    pub table_bytes: Option<usize>,
    /// Lobe directions per pixel (1 for closed-form zonal weights).
    pub lobes: usize,
    /// Bytes of the environment as the shader reads it.
    pub env_bytes: usize,
}

/// A frame: inputs for the GPU shading, or a CPU-rendered image.
#[derive(Debug)]
pub enum Frame {
    /// Shade on the window's device.
    Gpu {
        /// The G-buffer.
        surfaces: Arc<GpuSurfaces>,
        /// The environment.
        env: Arc<GpuEnvironment>,
        /// The material.
        material: Arc<GpuMaterial>,
        /// Object pixels per row (what a band of rows costs to shade).
        row_objects: Vec<u32>,
    },
    /// Shaded on the CPU (`ifd_render::render`), display-transformed.
    Cpu {
        /// The pixels.
        image: egui::ColorImage,
        /// The linear radiance (for the error against the reference).
        linear: Arc<ifd_image::Image>,
        /// Render time, seconds.
        seconds: f64,
    },
}

/// The worker's end of the channels.
#[derive(Debug)]
pub struct Handle {
    /// Settings to render (the latest wins).
    pub tx: Sender<Settings>,
    /// Answers.
    pub rx: Receiver<Event>,
    /// The thread (joined by [`Handle::stop`]).
    pub thread: Option<std::thread::JoinHandle<()>>,
}

/// Starts the worker; `gpu` is the device frames are shaded on and the
/// shader (whose kernels the worker compiles, off the UI thread) (`None`:
/// the CPU renderer); `wake` is called after every event (a repaint
/// request).
#[must_use]
pub fn spawn(
    gpu: Option<(Arc<GpuContext>, Arc<GpuShader>)>,
    wake: impl Fn() + Send + Sync + 'static,
) -> Handle {
    let (tx, rx_settings) = std::sync::mpsc::channel::<Settings>();
    let (tx_events, rx) = std::sync::mpsc::channel();
    let thread = std::thread::Builder::new()
        .name("ifd-envrender worker".into())
        .spawn(move || {
            let mut w = Worker {
                gpu,
                cache: Cache::default(),
            };
            let mut next = None;
            while let Some(mut s) = next.take().or_else(|| rx_settings.recv().ok()) {
                // only the latest settings matter
                while let Ok(newer) = rx_settings.try_recv() {
                    s = newer;
                }
                let send = |e: Event| {
                    let ok = tx_events.send(e).is_ok();
                    wake();
                    ok
                };
                let shaded = match w.frame(&s, &send) {
                    Ok(f) => f,
                    Err(e) => {
                        send(Event::Error(format!("{e:#}")));
                        continue;
                    }
                };
                // newer settings first: this frame's split sum would be stale
                match rx_settings.try_recv() {
                    Ok(newer) => {
                        next = Some(newer);
                        continue;
                    }
                    Err(std::sync::mpsc::TryRecvError::Disconnected) => break,
                    Err(std::sync::mpsc::TryRecvError::Empty) => {}
                }
                if let Err(e) = w.compare(&s, shaded, &send) {
                    send(Event::Error(format!("split sum: {e:#}")));
                }
            }
        })
        .ok();
    Handle { tx, rx, thread }
}

/// A value and the inputs it was made from.
type Slot<K, V> = Option<(K, Arc<V>)>;
/// The map's path and rotation (bits of the angle).
type EnvKey = (PathBuf, u64);
/// The map's path, rotation and the degree.
type ShKey = (PathBuf, u64, usize);

/// What the last settings produced, reused while its inputs stay the same.
#[derive(Default)]
struct Cache {
    /// The full map (background) and the one shading integrates.
    env: Slot<EnvKey, (EnvMap, EnvMap)>,
    sh: Slot<ShKey, Environment>,
    maps: Slot<ShKey, BandMaps>,
    material: Slot<(String, usize), Material>,
    scene: Option<(String, Scene)>,
    surface: Slot<MapKey, SurfaceMaps>,
    family: Slot<(String, usize, MapKey), RoughnessFamily>,
    gpu_env: Slot<(PathBuf, u64, usize, Variant), GpuEnvironment>,
    gpu_material: Slot<(String, usize, MapKey), GpuMaterial>,
    split_sum: Slot<EnvKey, SplitSum>,
}

/// What a frame was rendered from, for the split-sum comparison after it.
struct Shaded {
    maps: Arc<(EnvMap, EnvMap)>,
    env_key: EnvKey,
    brdf: Brdf,
    scene: Scene,
    camera: ifd_render::Camera,
    surface: Arc<SurfaceMaps>,
}

/// The albedo and roughness maps' paths.
type MapKey = (Option<PathBuf>, Option<PathBuf>);

/// Reads the texture maps (8/16-bit albedo sRGB-decoded, as `ifd render`).
///
/// # Errors
/// A map that cannot be read.
pub(crate) fn load_maps((albedo, roughness): &MapKey) -> Result<SurfaceMaps> {
    let read = |p: &PathBuf, srgb: bool, what: &'static str| -> Result<Texture> {
        let opts = ifd_image::ReadOptions {
            srgb_decode: srgb,
            ..Default::default()
        };
        let img = ifd_image::read_image(p, &opts)
            .with_context(|| format!("{what} {}", p.display()))?
            .image;
        Texture::new(img, what).with_context(|| format!("{}", p.display()))
    };
    Ok(SurfaceMaps {
        albedo: albedo
            .as_ref()
            .map(|p| read(p, true, "albedo map"))
            .transpose()?,
        roughness: roughness
            .as_ref()
            .map(|p| read(p, false, "roughness map"))
            .transpose()?,
        normal: None,
    })
}

struct Worker {
    gpu: Option<(Arc<GpuContext>, Arc<GpuShader>)>,
    cache: Cache,
}

/// Reuses `slot` when its key is `key`, else makes a new value.
fn cached<K: PartialEq + Clone, V>(
    slot: &mut Slot<K, V>,
    key: &K,
    make: impl FnOnce() -> Result<V>,
) -> Result<Arc<V>> {
    if let Some((k, v)) = slot
        && k == key
    {
        return Ok(Arc::clone(v));
    }
    let v = Arc::new(make()?);
    *slot = Some((key.clone(), Arc::clone(&v)));
    Ok(v)
}

impl Worker {
    /// The split sum of the frame `shaded` was rendered from, when `s` asks
    /// for the comparison.
    fn compare(
        &mut self,
        s: &Settings,
        shaded: Shaded,
        send: &(dyn Fn(Event) -> bool + Sync),
    ) -> Result<()> {
        let variant = match s.compare {
            Compare::Off => return Ok(()),
            Compare::SplitSum => Method::SplitSum,
            Compare::SampleRenderer => Method::SplitSumSampleRenderer,
        };
        if shaded.brdf.gltf_material().is_none() {
            // the panel says so; nothing to compare
            return Ok(());
        }
        let t = Instant::now();
        let env = &shaded.maps.1;
        let split = cached(&mut self.cache.split_sum, &shaded.env_key, || {
            send(Event::Progress(
                "baking the split sum (256-texel chain, irradiance, DFG)".into(),
            ));
            Ok(SplitSum::bake(env, 256)?)
        })?;
        send(Event::Progress("rendering the split sum".into()));
        let job = Job {
            maps: Some(&shaded.surface),
            split_sum: Some(&split),
            ..Job::new(
                shaded.scene,
                shaded.camera,
                env,
                &shaded.brdf,
                None,
                variant,
            )
        };
        let r = render(&job, &|_, _| {})?;
        send(Event::SplitSum {
            image: Arc::new(r.image),
            mask: Arc::new(r.mask),
            seconds: t.elapsed().as_secs_f64(),
        });
        Ok(())
    }

    /// Prepares and shades the frame of `s` (on the GPU: its inputs, shaded
    /// by the UI in bands).
    fn frame(&mut self, s: &Settings, send: &(dyn Fn(Event) -> bool + Sync)) -> Result<Shaded> {
        let path = s.env.clone().unwrap_or_else(bundled_env);
        let rot = s.env_rotate.to_bits();
        let env_key = (path.clone(), rot);
        let maps = cached(&mut self.cache.env, &env_key, || {
            send(Event::Progress(format!("reading {}", path.display())));
            load_env(&path, s.env_rotate)
        })?;
        let (full, env) = (&maps.0, &maps.1);
        let l = s.l_max;
        let sh_key = (path.clone(), rot, l);
        let sh = cached(&mut self.cache.sh, &sh_key, || {
            send(Event::Progress(format!("SH projection to L = {l}")));
            Ok(Environment::new(env.sh(l)?)?)
        })?;
        let band_maps = if s.variant == Variant::Maps {
            Some(cached(&mut self.cache.maps, &sh_key, || {
                send(Event::Progress(format!("per-band maps to L = {l}")));
                Ok(BandMaps::new(&sh)?)
            })?)
        } else {
            None
        };
        let brdf = Brdf::parse(&s.brdf).with_context(|| format!("BRDF {:?}", s.brdf))?;
        // what ISD tabulates: the glTF BRDF's three parts, else the BRDF
        let tabulated = brdf.tabulated()?;
        let scene = match &self.cache.scene {
            Some((name, sc)) if *name == s.scene => sc.clone(),
            _ => {
                send(Event::Progress(format!("loading the scene {}", s.scene)));
                let sc = Scene::parse(&s.scene, false)?;
                self.cache.scene = Some((s.scene.clone(), sc.clone()));
                sc
            }
        };
        // a glTF asset shaded with its own materials (the BRDF `gltf`)
        let asset_range = match &scene {
            Scene::Gltf(a) if brdf.gltf_material().is_some() => Some(a.roughness_range()),
            _ => None,
        };
        let map_key: MapKey = (s.albedo_map.clone(), s.roughness_map.clone());
        if asset_range.is_some() && (map_key.0.is_some() || map_key.1.is_some()) {
            anyhow::bail!(
                "the glTF asset {} brings its own textures: clear the albedo and roughness maps \
                 (or choose another BRDF to shade its geometry with them)",
                s.scene
            );
        }
        let surface = cached(&mut self.cache.surface, &map_key, || load_maps(&map_key))?;
        // a roughness map or a glTF asset: a family of tables over its range,
        // as `ifd render`
        let range = match (&surface.roughness, asset_range) {
            (Some(t), _) => {
                brdf.with_roughness(0.5).context("the roughness map")?;
                Some(t.range())
            }
            (None, r) => r,
        };
        let family = match range {
            Some(range) => {
                let key = (format!("{} {}", s.brdf, s.scene), l, map_key.clone());
                Some(cached(&mut self.cache.family, &key, || {
                    Ok(RoughnessFamily::build(&tabulated, l, range, 6, &|d, n| {
                        send(Event::Progress(format!("roughness tables {d}/{n}")));
                    })?)
                })?)
            }
            None => None,
        };
        let material = match &family {
            Some(f) => Arc::new(Material::new(
                f.materials()[0].brdf(),
                l,
                f.materials()[0].table().cloned(),
            )?),
            None => cached(&mut self.cache.material, &(s.brdf.clone(), l), || {
                build_material(&tabulated, l, &|d, n| {
                    if d % 8 == 0 || d == n {
                        send(Event::Progress(format!("lobe table {d}/{n}")));
                    }
                })
            })?,
        };
        if !brdf.is_isotropic() && !scene.has_tangents() {
            anyhow::bail!(
                "the anisotropic BRDF {} needs tangents, and {} has no texture coordinates",
                brdf.spec(),
                s.scene
            );
        }
        send(Event::Info(Info {
            env: format!(
                "{} ({}x{})",
                path.file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
                full.image().width(),
                full.image().height()
            ),
            brdf: brdf.spec().to_string(),
            table_bytes: match &family {
                Some(f) => Some(
                    f.materials()
                        .iter()
                        .filter_map(|m| m.table().map(LobeTable::weight_bytes))
                        .sum(),
                ),
                None => material.table().map(LobeTable::weight_bytes),
            },
            lobes: material.table().map_or(1, |t| t.basis().directions().len()),
            env_bytes: band_maps
                .as_ref()
                .map_or(sh.coeffs().data().len() * 4, |m| m.bytes()),
        }));
        let [w, h] = s.size;
        let camera = s.camera.camera(w, h)?;
        let background = s.background.then_some(full);
        let shaded = Shaded {
            maps: Arc::clone(&maps),
            env_key: env_key.clone(),
            brdf: brdf.clone(),
            scene: scene.clone(),
            camera,
            surface: Arc::clone(&surface),
        };
        if let Some((ctx, shader)) = &self.gpu {
            let gkey = (path, rot, l, s.variant);
            let uploads = cached(&mut self.cache.gpu_env, &gkey, || {
                Ok(match &band_maps {
                    Some(m) => GpuEnvironment::maps(ctx, m)?,
                    None => GpuEnvironment::sh(ctx, &sh)?,
                })
            })
            .and_then(|e| {
                let key = (format!("{} {}", s.brdf, s.scene), l, map_key.clone());
                let m = cached(&mut self.cache.gpu_material, &key, || {
                    Ok(match &family {
                        Some(f) => GpuMaterial::family(ctx, f)?,
                        None => GpuMaterial::new(ctx, &material)?,
                    })
                })?;
                Ok((e, m))
            });
            // beyond the device's limits (L > 63, maps beyond a binding):
            // this frame on the CPU, and the status bar says why
            let (genv, gmat) = match uploads {
                Ok(u) => u,
                Err(e) => {
                    send(Event::Fallback(format!("{e:#}")));
                    Self::render_cpu(
                        s,
                        scene,
                        camera,
                        env,
                        background,
                        &brdf,
                        (&material, &surface, family.as_deref()),
                        send,
                    )?;
                    return Ok(shaded);
                }
            };
            // the kernel for this degree, compiled here rather than on the UI thread
            shader.pipeline(ctx, l)?;
            let gltf = brdf.gltf_material();
            let px = ifd_render::pixels(&scene, &camera, Some(&surface))?;
            let points: Vec<SurfacePoint> = px
                .iter()
                .map(|p| SurfacePoint::from_pixel_with(p, background, gltf.as_ref()))
                .collect();
            let surfaces = Arc::new(GpuSurfaces::upload(ctx, w, h, &points)?);
            let row_objects = px
                .chunks_exact(w)
                .map(|row| row.iter().filter(|p| p.surface.is_some()).count() as u32)
                .collect();
            send(Event::Frame(Frame::Gpu {
                surfaces,
                env: genv,
                material: gmat,
                row_objects,
            }));
            return Ok(shaded);
        }
        Self::render_cpu(
            s,
            scene,
            camera,
            env,
            background,
            &brdf,
            (&material, &surface, family.as_deref()),
            send,
        )?;
        Ok(shaded)
    }

    /// The frame on the CPU (`ifd_render::render`), display-transformed.
    #[allow(clippy::too_many_arguments)]
    fn render_cpu(
        s: &Settings,
        scene: Scene,
        camera: ifd_render::Camera,
        env: &EnvMap,
        background: Option<&EnvMap>,
        brdf: &Brdf,
        (material, surface, family): (&Material, &SurfaceMaps, Option<&RoughnessFamily>),
        send: &(dyn Fn(Event) -> bool + Sync),
    ) -> Result<()> {
        let t = Instant::now();
        let method = match s.variant {
            Variant::Sh => Method::Isd,
            Variant::Maps => Method::IsdMaps,
        };
        let job = Job {
            background,
            maps: Some(surface),
            family,
            // the fast lanes, as `ifd render` by default
            precision: Precision::F32,
            // a family (roughness map, glTF asset) shades alone
            ..Job::new(
                scene,
                camera,
                env,
                brdf,
                family.is_none().then_some(material),
                method,
            )
        };
        let r = render(&job, &|_, _| {})?;
        let tm = Tonemap::parse(&s.tonemap)?;
        let image = display_image(&r.image, tm, s.exposure);
        send(Event::Frame(Frame::Cpu {
            image,
            linear: Arc::new(r.image),
            seconds: t.elapsed().as_secs_f64(),
        }));
        Ok(())
    }
}

/// The full map (background) and the one the shading integrates: averaged
/// down to 128x64 when that divides the map, as `ifd render` does.
///
/// # Errors
/// A map that cannot be read or is not 2:1.
pub fn load_env(path: &std::path::Path, rotate: f64) -> Result<(EnvMap, EnvMap)> {
    let img = ifd_image::read(path).with_context(|| format!("{}", path.display()))?;
    let full = EnvMap::new(img, rotate).with_context(|| format!("{}", path.display()))?;
    let (mw, mh) = (full.image().width(), full.image().height());
    let (ew, eh) = if mw % 128 == 0 && mh % 64 == 0 {
        (128, 64)
    } else {
        (mw, mh)
    };
    let env = full.downsampled(ew, eh)?;
    Ok((full, env))
}

/// Closed form for Lambert and Phong, else a lobe table at `ifd render`'s
/// default resolution.
///
/// `progress(done, total)` after each table entry.
///
/// # Errors
/// Table errors.
pub(crate) fn build_material(
    brdf: &Brdf,
    l: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Material> {
    if let Ok(m) = Material::new(brdf, l, None) {
        return Ok(m);
    }
    let nt = default_theta_entries(brdf);
    let np = (2 * nt).min(128);
    let t = LobeTable::build(brdf, l, nt, np, progress)?;
    Ok(Material::new(brdf, l, Some(t))?)
}

/// `ifd render`'s 8-bit display transform, as egui pixels.
#[must_use]
pub fn display_image(img: &ifd_image::Image, tm: Tonemap, exposure: f32) -> egui::ColorImage {
    let c = img.channels();
    let byte = |v: f32| (tm.display(v, exposure) * 255.0).round() as u8;
    let pixels = img
        .data()
        .chunks_exact(c)
        .map(|p| {
            let (r, g, b) = if c >= 3 {
                (p[0], p[1], p[2])
            } else {
                (p[0], p[0], p[0])
            };
            egui::Color32::from_rgb(byte(r), byte(g), byte(b))
        })
        .collect();
    egui::ColorImage::new([img.width(), img.height()], pixels)
}

impl Handle {
    /// Closes the requests and waits (at most `limit`) for the thread.
    pub fn stop(&mut self, limit: std::time::Duration) {
        stop_thread(&mut self.tx, &mut self.thread, limit);
    }
}

/// Closes a thread's request channel (replacing `tx` by a closed one) and
/// waits (at most `limit`) for it to finish what it is doing, so that nothing
/// runs on the GPU device while the window tears it down.
pub(crate) fn stop_thread<T>(
    tx: &mut Sender<T>,
    thread: &mut Option<std::thread::JoinHandle<()>>,
    limit: std::time::Duration,
) {
    let (closed, _) = std::sync::mpsc::channel();
    *tx = closed;
    let t0 = std::time::Instant::now();
    if let Some(t) = thread.take() {
        while !t.is_finished() && t0.elapsed() < limit {
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        if t.is_finished() {
            t.join().ok();
        }
    }
}
