//! ISD Fig. 7 (`ifd-paper isd-visibility`): self-shadowed ISD shading on a
//! mesh (Eq. 25, Appendix A) against its ray-traced reference, as `L` grows,
//! beside unshadowed ISD.
//!
//! Every image is an `ifd render` frame ([`ifd_render::render`]):
//! the reference is `quadrature` with [`Shadows`] (the visibility of `2 x 2`
//! nodes per texel traced from each pixel's point), the shadowed images
//! `isd` with the visibility per vertex built once at the highest degree
//! (each degree's material reads its first `(L + 1)^2` coefficients), the
//! unshadowed ones `isd` without shadows.

use std::sync::Arc;
use std::time::Instant;

use ifd_image::Image;
use ifd_render::Camera;
use ifd_render::EnvMap;
use ifd_render::Mesh;
use ifd_render::Result;
use ifd_render::Scene;
use ifd_render::Shadows;
use ifd_render::{Job, Method, relative_rms, render};
use ifd_shade::Brdf;
use ifd_shade::Material;

/// What the study renders: a mesh seen by a camera under a map.
#[derive(Debug)]
pub struct VisibilityScene<'a> {
    /// The mesh.
    pub mesh: Arc<Mesh>,
    /// The camera.
    pub camera: Camera,
    /// The environment (piecewise constant; its texels are the reference's
    /// quadrature).
    pub env: &'a EnvMap,
    /// The BRDF.
    pub brdf: &'a Brdf,
}

/// The study's images and errors (ISD Fig. 7).
#[derive(Debug)]
pub struct VisibilityStudy {
    /// Per degree: `(L, relative RMS of ISD with visibility, of ISD
    /// without)` against the reference.
    pub rows: Vec<(usize, f64, f64)>,
    /// The reference.
    pub reference: Image,
    /// ISD with visibility at the highest degree.
    pub shadowed: Image,
    /// ISD without visibility at the highest degree.
    pub unshadowed: Image,
    /// Object pixels.
    pub mask: Vec<bool>,
    /// Seconds: reference, visibility and product matrix, ISD frame with
    /// shadows at the highest degree.
    pub seconds: [f64; 3],
}

/// Renders the reference once, then ISD with and without visibility with
/// each of `materials` (one per degree, ascending; the visibility is cast
/// with `rays` rays per vertex at the highest), and measures them over the
/// object.
///
/// # Errors
/// Shading, SH and render errors (nothing visible, too few rays).
pub fn study(
    scene: &VisibilityScene<'_>,
    materials: &[Material],
    rays: usize,
    progress: &dyn Fn(&str),
) -> Result<VisibilityStudy> {
    let l_max = materials.iter().map(Material::l_max).max().unwrap_or(0);
    let job = |method, material, shadows| Job {
        shadows,
        ..Job::new(
            Scene::Mesh(scene.mesh.clone()),
            scene.camera,
            scene.env,
            scene.brdf,
            material,
            method,
        )
    };
    progress("reference (ray-traced visibility)");
    let t = Instant::now();
    let traced = Shadows::traced(scene.mesh.clone(), scene.env)?;
    let reference = render(&job(Method::Quadrature, None, Some(&traced)), &|_, _| {})?;
    let t_ref = t.elapsed().as_secs_f64();
    progress("visibility per vertex and product matrix");
    let t = Instant::now();
    let shadows = Shadows::new(
        scene.mesh.clone(),
        scene.env,
        l_max,
        rays.max((l_max + 1) * (l_max + 1)),
        &|_, _| {},
    )?;
    let t_setup = t.elapsed().as_secs_f64();
    let mask = reference.mask;
    let mut rows = Vec::new();
    let (mut shadowed, mut unshadowed) = (None, None);
    let mut t_frame = 0.0;
    for m in materials {
        let l = m.l_max();
        progress(&format!("ISD at L = {l}"));
        let t = Instant::now();
        let with = render(&job(Method::Isd, Some(m), Some(&shadows)), &|_, _| {})?.image;
        t_frame = t.elapsed().as_secs_f64();
        let without = render(&job(Method::Isd, Some(m), None), &|_, _| {})?.image;
        rows.push((
            l,
            relative_rms(&with, &reference.image, &mask),
            relative_rms(&without, &reference.image, &mask),
        ));
        shadowed = Some(with);
        unshadowed = Some(without);
    }
    let empty = || Image::from_vec(1, 1, 1, vec![0.0]);
    Ok(VisibilityStudy {
        rows,
        reference: reference.image,
        shadowed: shadowed.map_or_else(empty, Ok)?,
        unshadowed: unshadowed.map_or_else(empty, Ok)?,
        mask,
        seconds: [t_ref, t_setup, t_frame],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use ifd_render::torus_mesh;

    /// On a torus the three-step shader converges to the ray-traced
    /// reference as L grows, while the unshadowed one stalls.
    #[test]
    fn shadowed_isd_converges_to_the_ray_traced_reference() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/forest.hdr");
        let img = ifd_image::read(path).expect("bundled map");
        let env = EnvMap::new(img, 30.0)
            .expect("a 2:1 map")
            .downsampled(32, 16)
            .expect("a divisor");
        let mesh = Arc::new(torus_mesh(1.0, 0.4, 64, 32).unwrap());
        let brdf = Brdf::parse("phong:s=8").unwrap();
        let materials: Vec<Material> = [4, 8, 12]
            .iter()
            .map(|&l| Material::new(&brdf, l, None).unwrap())
            .collect();
        let scene = VisibilityScene {
            mesh,
            camera: Camera::new(
                DVec3::new(0.0, -2.4, 1.7),
                DVec3::ZERO,
                DVec3::Z,
                40.0,
                40,
                40,
            )
            .unwrap(),
            env: &env,
            brdf: &brdf,
        };
        let st = study(&scene, &materials, 2048, &|_| {}).unwrap();
        for r in &st.rows {
            eprintln!(
                "L = {}: with visibility {:.2e}, unshadowed {:.2e}",
                r.0, r.1, r.2
            );
        }
        let (l4, l12) = (st.rows[0], st.rows[2]);
        assert!(l12.1 < 0.5 * l4.1, "{:?}", st.rows);
        assert!(l12.1 < 0.5 * l12.2, "{:?}", st.rows);
        assert!(l12.1 < 0.02, "{:?}", st.rows);
    }
}
