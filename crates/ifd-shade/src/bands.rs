//! The per-band prefiltered environment `Ehat_l(d)` of Eq. 22 as a source
//! for shading: the [`Bands`] trait and the weighted sums of its bands.

/// A source of the per-band prefiltered environment `Ehat_l(d)` of Eq. 22.
pub trait Bands: Sync {
    /// Maximum degree `L`.
    fn l_max(&self) -> usize;
    /// Channels.
    fn channels(&self) -> usize;
    /// `Ehat_l(d)` for every band: `out[l C + c]`; `y` is scratch of
    /// `(L + 1)^2` values.
    fn bands_into(&self, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        self.bands_from(0, d, y, out);
    }
    /// [`Self::bands_into`] for the bands `l >= l0` only (the others of `out`
    /// are left as they are): a lobe serves the bands from
    /// [`crate::table::LobeBasis::first_band`] up.
    fn bands_from(&self, l0: usize, d: [f64; 3], y: &mut [f64], out: &mut [f64]);
    /// The weighted sum of the bands at every lobe of a point (Eq. 22's
    /// double sum): `out[p C + c] = sum_k sum_{l >= l0[k]} w[(k (L + 1) + l)
    /// P + p] Ehat_l(d_k)[c]` for `P = parts` weights per lobe and band
    /// (overwritten; `bands` is scratch of `4 (L + 1) C` values, `y` of
    /// `(L + 1)^2`). The default runs [`Self::bands_from`] per lobe;
    /// [`crate::Environment`] runs its lobes in vector lanes.
    #[expect(
        clippy::too_many_arguments,
        reason = "one point's lobes, weights and scratch"
    )]
    fn lobe_sums(
        &self,
        l0: &[usize],
        d: &[[f64; 3]],
        w: &[f64],
        parts: usize,
        y: &mut [f64],
        bands: &mut [f64],
        out: &mut [f64],
    ) {
        let (nb, ch) = (self.l_max() + 1, self.channels());
        out[..parts * ch].fill(0.0);
        for (k, (&l0, &d)) in l0.iter().zip(d).enumerate() {
            let l0 = l0.min(nb);
            self.bands_from(l0, d, y, bands);
            add_weighted(
                &w[k * nb * parts..],
                l0,
                nb,
                parts,
                ch,
                &bands[..nb * ch],
                out,
            );
        }
    }
}

/// `out[p C + c] += w[l P + p] b[l C + c]` over `l0 <= l < nb`, in order of
/// `l` (the reference order of the weighted sums).
pub(crate) fn add_weighted(
    w: &[f64],
    l0: usize,
    nb: usize,
    parts: usize,
    ch: usize,
    b: &[f64],
    out: &mut [f64],
) {
    for l in l0..nb {
        let band = &b[l * ch..(l + 1) * ch];
        for (p, o) in out[..parts * ch].chunks_exact_mut(ch).enumerate() {
            let lam = w[l * parts + p];
            for (o, b) in o.iter_mut().zip(band) {
                *o += lam * b;
            }
        }
    }
}
