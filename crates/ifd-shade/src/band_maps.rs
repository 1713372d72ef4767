//! The per-band prefiltered environment tabulated on equirectangular maps:
//! [`BandMaps`], a [`Bands`] source with bicubic lookups.

use ifd_sphere::{ShCoeffs, pi_l};

use crate::bands::Bands;
use crate::environment::Environment;
use crate::error::Result;

/// The per-band prefiltered environment tabulated on equirectangular maps
/// (the variant of Eq. 22's middle line): band `l`'s map holds `Ehat_l` at the
/// pixel centres (exact synthesis, FFT + Legendre), and lookups are bicubic
/// (Catmull-Rom), wrapping in azimuth and across the poles (row `-1 - v` is
/// row `v` half a turn away). Maps are `2N x N` with `N = 8 (L + 1)` (at least
/// 32): about 16 samples per wavelength of the highest band, where the
/// Catmull-Rom error is below 1e-3 of the band's amplitude. Memory: `(L + 1)
/// 2 N^2 C` f32 values (`L = 30`, RGB: 46 MB).
#[derive(Clone, Debug)]
pub struct BandMaps {
    l_max: usize,
    channels: usize,
    width: usize,
    height: usize,
    /// `[band][row][column][channel]`.
    data: Vec<f32>,
}

impl BandMaps {
    /// Tabulates the bands of `env`.
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn new(env: &Environment) -> Result<Self> {
        let l_max = env.l_max();
        let ch = env.channels();
        let h = (8 * (l_max + 1)).max(32);
        let w = 2 * h;
        let t = ifd_sphere::EquirectTransform::new(l_max, w, h)?;
        let mut data = Vec::with_capacity((l_max + 1) * w * h * ch);
        for l in 0..=l_max {
            let mut band = ShCoeffs::zeros(l_max, ch)?;
            let p = pi_l(l);
            let range = l * l * ch..(l + 1) * (l + 1) * ch;
            for (o, e) in band.data_mut()[range.clone()]
                .iter_mut()
                .zip(&env.coeffs().data()[range])
            {
                *o = p * e;
            }
            data.extend_from_slice(t.synthesize(&band)?.data());
        }
        Ok(Self {
            l_max,
            channels: ch,
            width: w,
            height: h,
            data,
        })
    }

    /// Map size `(W, H)`.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The maps, `[band][row][column][channel]` f32 (rows from the zenith).
    #[must_use]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Bytes of the maps.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.data.len() * 4
    }
}

impl Bands for BandMaps {
    fn l_max(&self) -> usize {
        self.l_max
    }
    fn channels(&self) -> usize {
        self.channels
    }
    fn bands_from(&self, l0: usize, d: [f64; 3], _y: &mut [f64], out: &mut [f64]) {
        let (w, h, ch) = (self.width, self.height, self.channels);
        let taps = ifd_sphere::bicubic_taps(d, w, h);
        let band_len = w * h * ch;
        for l in l0..=self.l_max {
            let base = &self.data[l * band_len..(l + 1) * band_len];
            for c in 0..ch {
                let mut acc = 0.0;
                for (t, wt) in &taps {
                    acc += wt * f64::from(base[t * ch + c]);
                }
                out[l * ch + c] = acc;
            }
        }
    }
}
