//! The progressive Monte Carlo reference of the current view, on a thread of
//! its own: started when the camera is still, refined pass after pass
//! (environment and BRDF importance sampling with MIS, `ifd_render::estimate_mc`),
//! and, once it has enough samples, the error of ISD at a ladder of degrees
//! against it (the error-against-`L` curve of the current view).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender};

use anyhow::{Context, Result};
use ifd_image::Image;
use ifd_render::EnvMap;
use ifd_render::Scene;
use ifd_render::{Job, Method, relative_rms, render};
use ifd_shade::Brdf;
use ifd_shade::Material;

use crate::settings::{Settings, bundled_env};
use crate::worker::{build_material, load_env, load_maps};

/// The maps of a path and rotation (the full map and the integrated one).
type EnvCache = Option<((PathBuf, u64), Arc<(EnvMap, EnvMap)>)>;

/// What every render of the view shares: scene, camera, environment,
/// background, BRDF, texture maps.
type View<'a> = (
    &'a Scene,
    ifd_render::Camera,
    &'a EnvMap,
    Option<&'a EnvMap>,
    &'a Brdf,
    &'a ifd_render::SurfaceMaps,
);

/// A render job of the view.
fn job<'a>(
    (scene, camera, env, background, brdf, maps): View<'a>,
    method: Method,
    material: Option<&'a Material>,
    spp: usize,
    seed: u64,
) -> Job<'a> {
    Job {
        background,
        spp,
        seed,
        maps: Some(maps),
        ..Job::new(scene.clone(), camera, env, brdf, material, method)
    }
}

/// Samples per pixel added by one pass.
pub const PASS_SPP: usize = 8;
/// The reference stops refining here.
pub const MAX_SPP: usize = 1024;
/// Samples per pixel at which the error-against-`L` curve is computed (and
/// again at the last).
const CURVE_AT: [usize; 2] = [64, 512];

/// What to render: the settings and their generation (the UI's count of
/// settings changes; answers for older generations are dropped).
#[derive(Clone, Debug)]
pub struct Request {
    /// The view.
    pub settings: Settings,
    /// The generation.
    pub generation: u64,
}

/// What the reference thread tells the UI.
#[derive(Debug)]
pub enum RefEvent {
    /// The reference after a pass: the mean so far (linear radiance) and its
    /// object mask.
    Pass {
        /// Of the request.
        generation: u64,
        /// Mean radiance.
        image: Arc<Image>,
        /// Object pixels, row-major.
        mask: Arc<Vec<bool>>,
        /// Samples per pixel so far.
        spp: usize,
    },
    /// ISD's relative RMS error against the reference at a ladder of degrees.
    Curve {
        /// Of the request.
        generation: u64,
        /// `(L, relative RMS)`.
        points: Vec<(usize, f64)>,
        /// The reference's samples per pixel.
        spp: usize,
    },
    /// The reference cannot be made (the message).
    Error(String),
}

/// The thread's ends of the channels.
#[derive(Debug)]
pub struct Handle {
    /// Requests (the latest wins; a new one stops the current).
    pub tx: Sender<Request>,
    /// Answers.
    pub rx: Receiver<RefEvent>,
    /// The thread (joined by [`Handle::stop`]).
    pub thread: Option<std::thread::JoinHandle<()>>,
}

/// Starts the reference thread; `wake` asks the UI for a frame.
#[must_use]
pub fn spawn(wake: impl Fn() + Send + 'static) -> Handle {
    let (tx, rx_req) = std::sync::mpsc::channel::<Request>();
    let (tx_ev, rx) = std::sync::mpsc::channel();
    let thread = std::thread::Builder::new()
        .name("ifd-envrender reference".into())
        .spawn(move || {
            let mut envs: EnvCache = None;
            let mut next = rx_req.recv().ok();
            while let Some(req) = next.take() {
                let send = |e: RefEvent| {
                    let ok = tx_ev.send(e).is_ok();
                    wake();
                    ok
                };
                match refine(&req, &rx_req, &mut envs, &send) {
                    Ok(Some(newer)) => next = Some(newer),
                    Ok(None) => next = rx_req.recv().ok(),
                    Err(e) => {
                        send(RefEvent::Error(format!("{e:#}")));
                        next = rx_req.recv().ok();
                    }
                }
            }
        })
        .ok();
    Handle { tx, rx, thread }
}

/// Refines the reference of `req` until [`MAX_SPP`] or a newer request,
/// which it returns.
fn refine(
    req: &Request,
    rx: &Receiver<Request>,
    envs: &mut EnvCache,
    send: &dyn Fn(RefEvent) -> bool,
) -> Result<Option<Request>> {
    let s = &req.settings;
    let path = s.env.clone().unwrap_or_else(bundled_env);
    let key = (path.clone(), s.env_rotate.to_bits());
    let maps = match envs {
        Some((k, m)) if *k == key => Arc::clone(m),
        _ => {
            let m = Arc::new(load_env(&path, s.env_rotate)?);
            *envs = Some((key, Arc::clone(&m)));
            m
        }
    };
    let brdf = Brdf::parse(&s.brdf).with_context(|| format!("BRDF {:?}", s.brdf))?;
    let scene = Scene::parse(&s.scene, false)?;
    let surface = load_maps(&(s.albedo_map.clone(), s.roughness_map.clone()))?;
    // ISD at other degrees with one material: not for a roughness map or a
    // glTF asset's own materials (each degree would need a table family)
    let one_material = surface.roughness.is_none()
        && !(matches!(scene, Scene::Gltf(_)) && brdf.gltf_material().is_some());
    let camera = s.camera.camera(s.size[0], s.size[1])?;
    let view: View<'_> = (
        &scene,
        camera,
        &maps.1,
        s.background.then_some(&maps.0),
        &brdf,
        &surface,
    );
    let mut mean: Option<(Vec<f64>, Vec<bool>, usize, usize)> = None;
    let mut spp = 0;
    while spp < MAX_SPP {
        match rx.try_recv() {
            Ok(mut newer) => {
                while let Ok(n) = rx.try_recv() {
                    newer = n;
                }
                return Ok(Some(newer));
            }
            // the app is closing
            Err(std::sync::mpsc::TryRecvError::Disconnected) => return Ok(None),
            Err(std::sync::mpsc::TryRecvError::Empty) => {}
        }
        let pass = render(
            &job(view, Method::Mc, None, PASS_SPP, spp as u64 + 1),
            &|_, _| {},
        )?;
        let (w, h, c) = (
            pass.image.width(),
            pass.image.height(),
            pass.image.channels(),
        );
        let m = mean.get_or_insert_with(|| (vec![0.0; w * h * c], pass.mask.clone(), w, h));
        let k = (spp / PASS_SPP) as f64;
        for (a, v) in m.0.iter_mut().zip(pass.image.data()) {
            *a += (f64::from(*v) - *a) / (k + 1.0);
        }
        spp += PASS_SPP;
        let image = Arc::new(Image::from_vec(
            w,
            h,
            c,
            m.0.iter().map(|v| *v as f32).collect(),
        )?);
        send(RefEvent::Pass {
            generation: req.generation,
            image: Arc::clone(&image),
            mask: Arc::new(m.1.clone()),
            spp,
        });
        if CURVE_AT.contains(&spp) {
            // empty without one material (the panel says why)
            let points = if one_material {
                curve(s, &brdf, &image, &m.1, |material, method| {
                    Ok(render(&job(view, method, Some(material), 0, 0), &|_, _| {})?.image)
                })?
            } else {
                Vec::new()
            };
            send(RefEvent::Curve {
                generation: req.generation,
                points,
                spp,
            });
        }
    }
    Ok(None)
}

/// ISD's error against `reference` at degrees 2, 4, ... up to the current `L`.
fn curve(
    s: &Settings,
    brdf: &Brdf,
    reference: &Image,
    mask: &[bool],
    render_isd: impl Fn(&Material, Method) -> Result<Image>,
) -> Result<Vec<(usize, f64)>> {
    let mut degrees: Vec<usize> = (2..s.l_max).step_by(2).collect();
    degrees.push(s.l_max);
    let mut points = Vec::new();
    let tabulated = brdf.tabulated()?;
    for l in degrees {
        let material = build_material(&tabulated, l, &|_, _| {})?;
        let img = render_isd(&material, Method::Isd)?;
        points.push((l, relative_rms(&img, reference, mask)));
    }
    Ok(points)
}

impl Handle {
    /// Closes the requests and waits (at most `limit`) for the thread.
    pub fn stop(&mut self, limit: std::time::Duration) {
        crate::worker::stop_thread(&mut self.tx, &mut self.thread, limit);
    }
}
