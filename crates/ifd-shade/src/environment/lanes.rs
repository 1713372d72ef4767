//! [`Environment`]'s lobe lookups in `f32` vector lanes
//! ([`Precision::F32`](super::Precision::F32)): the lobes of one point or of
//! a batch of points, `N` at a time.

use super::Environment;

impl Environment {
    /// [`Bands::lobe_sums`](crate::Bands::lobe_sums) in `f32`: the lobes `N` at a time in vector
    /// lanes, each lane's bands weighted in its lane, the lanes' sums added
    /// in `f64`.
    pub(super) fn lobe_sums_f32<const N: usize>(
        &self,
        l0: &[usize],
        d: &[[f64; 3]],
        w: &[f64],
        parts: usize,
        owner: Option<(&[u32], &[usize])>,
        out: &mut [f64],
    ) {
        thread_local! {
            /// The kernel's lane accumulators and weights, kept between points.
            static LANES: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        let ch = self.channels();
        let nb = self.l_max() + 1;
        LANES.with_borrow_mut(|buf| {
            buf.resize((nb * ch + nb * parts + parts * ch) * N, 0.0);
            let (lanes, _) = buf.as_chunks_mut::<N>();
            ifd_simd::run_vectorized(LobeSumsF32 {
                env: self,
                l0,
                d,
                w,
                parts,
                lanes,
                owner,
                out,
            });
        });
    }
}

/// The lobe-major order of a batch's lobes (each point's lobes
/// contiguous, `owner[k]` the point of lobe `k`): the first lobe of every
/// point, then the second of every point, and so on (a counting sort by
/// the rank within the point, stable). A chunk of lanes then holds the
/// same lobe of sixteen points, whose first bands agree, so the chunk's SH
/// sums skip the bands below it (an in-plane table's lobe `j` serves bands
/// `j..=L`), where chunks of mixed lobes skip none. Each point still
/// receives its lobes' sums in its own order: the same bits.
pub(super) fn lobe_major(owner: &[u32], counts: &mut Vec<usize>, order: &mut Vec<usize>) {
    let n = owner.len();
    order.clear();
    // lobes per point, when every point has as many (a material's batch)
    let per = owner.iter().take_while(|&&p| p == owner[0]).count();
    let uniform = per > 0
        && n.is_multiple_of(per)
        && owner
            .chunks(per)
            .zip(owner[0]..)
            .all(|(c, point)| c.iter().all(|&p| p == point));
    if uniform {
        let points = n / per;
        order.extend((0..per).flat_map(|r| (0..points).map(move |p| p * per + r)));
        return;
    }
    // counts of each rank, then their first positions; then place
    counts.clear();
    let mut start = 0;
    for k in 0..n {
        if owner[k] != owner[start] {
            start = k;
        }
        let r = k - start;
        if r == counts.len() {
            counts.push(0);
        }
        counts[r] += 1;
    }
    let mut at = 0;
    for c in counts.iter_mut() {
        (*c, at) = (at, at + *c);
    }
    order.resize(n, 0);
    start = 0;
    for k in 0..n {
        if owner[k] != owner[start] {
            start = k;
        }
        let r = k - start;
        order[counts[r]] = k;
        counts[r] += 1;
    }
}

/// [`Environment::lobe_sums_f32`]'s work for one point, compiled for the
/// CPU's vectors as a whole ([`ifd_simd::VectorKernel`]): per chunk of `N`
/// lobes the SH kernel, the lanes' weights (zero below each lobe's first
/// band), their weighted sums per part and channel in the lanes, and the
/// lanes' sums in `f64`.
struct LobeSumsF32<'a, const N: usize> {
    env: &'a Environment,
    l0: &'a [usize],
    d: &'a [[f64; 3]],
    w: &'a [f64],
    parts: usize,
    /// Scratch: `(L + 1) C` accumulators, `(L + 1) P` weights, `P C` sums.
    lanes: &'a mut [[f32; N]],
    /// The point of each lobe and the order the lanes take the lobes in
    /// (`None`: one point, in order); a point's `P C` sums start at
    /// `out[point P C]`.
    owner: Option<(&'a [u32], &'a [usize])>,
    out: &'a mut [f64],
}

impl<const N: usize> ifd_simd::VectorKernel for LobeSumsF32<'_, N> {
    type Output = ();
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        let Self {
            env,
            l0,
            d,
            w,
            parts,
            lanes,
            owner,
            out,
        } = self;
        let ch = env.channels();
        let nb = env.l_max() + 1;
        let (acc, rest) = lanes.split_at_mut(nb * ch);
        let (wl, sums) = rest.split_at_mut(nb * parts);
        let n = d.len();
        for q0 in (0..n).step_by(N) {
            let len = N.min(n - q0);
            // the chunk's lobes (the last one again past `len`, unused)
            let lobes: [usize; N] = std::array::from_fn(|k| {
                let q = q0 + k.min(len - 1);
                owner.map_or(q, |(_, order)| order[q])
            });
            let lobes = &lobes[..len];
            let lo = lobes.iter().map(|&i| l0[i]).min().unwrap_or(nb).min(nb);
            let mut dirs = [[0.0f32, 0.0, 1.0]; N];
            for (v, &i) in dirs.iter_mut().zip(lobes) {
                *v = d[i].map(|x| x as f32);
            }
            env.sh
                .band_sums_f32_lanes(lo, &dirs, &env.scaled32, ch, acc);
            wl[lo * parts..].fill([0.0; N]);
            for (k, &i) in lobes.iter().enumerate() {
                let wk = &w[i * nb * parts..(i + 1) * nb * parts];
                for (j, &v) in wk.iter().enumerate().skip(l0[i].min(nb) * parts) {
                    wl[j][k] = v as f32;
                }
            }
            for p in 0..parts {
                for c in 0..ch {
                    let mut s = [0.0f32; N];
                    for l in lo..nb {
                        let (a, b) = (&wl[l * parts + p], &acc[l * ch + c]);
                        for k in 0..N {
                            s[k] = a[k].mul_add(b[k], s[k]);
                        }
                    }
                    sums[p * ch + c] = s;
                }
            }
            match owner {
                None => {
                    for (o, s) in out[..parts * ch].iter_mut().zip(sums.iter()) {
                        *o += s.iter().map(|&v| f64::from(v)).sum::<f64>();
                    }
                }
                Some((own, _)) => {
                    for (k, &i) in lobes.iter().enumerate() {
                        let pt = own[i] as usize;
                        let o = &mut out[pt * parts * ch..(pt + 1) * parts * ch];
                        for (o, s) in o.iter_mut().zip(sums.iter()) {
                            *o += f64::from(s[k]);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::lobe_major;

    /// Lobe-major order: by rank within the point, points in order within
    /// a rank, for points of different lobe counts.
    #[test]
    fn lobe_major_orders_by_rank_then_point() {
        let owner = [0, 0, 0, 1, 2, 2, 2, 2, 3, 3];
        let (mut counts, mut order) = (Vec::new(), Vec::new());
        lobe_major(&owner, &mut counts, &mut order);
        assert_eq!(order, [0, 3, 4, 8, 1, 5, 9, 2, 6, 7]);
        // as many lobes per point: the direct order
        lobe_major(&[0, 0, 0, 1, 1, 1], &mut counts, &mut order);
        assert_eq!(order, [0, 3, 1, 4, 2, 5]);
        // equal runs that are not points' (a point split in two) take the sort
        lobe_major(&[0, 0, 1, 1, 1, 1], &mut counts, &mut order);
        assert_eq!(order, [0, 2, 1, 3, 4, 5]);
        lobe_major(&[], &mut counts, &mut order);
        assert!(order.is_empty());
    }
}
