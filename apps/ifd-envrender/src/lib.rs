//! The environment renderer (`ifd-envrender`): an object lit by an
//! environment map, shaded by ISD (ISD Eq. 22) in a window, with the GPU
//! kernels of `ifd_gpu::GpuShader` on the window's own device.
//!
//! - [`settings`]: what the user chose (map, scene, BRDF, `L`, variant,
//!   camera, display), persisted between sessions.
//! - [`orbit`]: the orbit camera.
//! - [`worker`]: everything slow, off the UI thread: reading the map, its SH
//!   projection, the per-band maps, lobe tables, the G-buffer; the CPU
//!   renderer when the GPU path is not used.
//! - [`reference`](mod@reference): the progressive Monte Carlo reference of the current
//!   view and ISD's error against it over `L`.
//! - [`app`]: the egui UI, the banded GPU shading and display, automated
//!   runs (`--screenshot`, `--exit`).
//!
//! Invariant: the viewport shows, pixel for pixel, what `ifd render` writes
//! for the same view and display settings (tested under Xvfb within 2/255).

pub mod app;
pub mod orbit;
pub mod reference;
pub mod settings;
pub mod worker;
