//! Fewer points, same picture: per time slice, the first, lowest, highest and last point.

/// `points` sorted by time and cut into `slices` equal time slices over their span; each
/// slice keeps its first, lowest, highest and last point, in time order (fewer when they
/// coincide). At most `4 * slices` points come out; every extreme stays. Points in fewer than
/// `4 * slices` come out unchanged (sorted).
pub fn envelope(points: &[(f64, f64)], slices: usize) -> Vec<(f64, f64)> {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let slices = slices.max(1);
    if sorted.len() <= 4 * slices {
        return sorted;
    }
    let (first, last) = (sorted[0].0, sorted[sorted.len() - 1].0);
    let span = last - first;
    let slice_of = |x: f64| {
        if span > 0.0 {
            (((x - first) / span * slices as f64) as usize).min(slices - 1)
        } else {
            0
        }
    };
    let mut out = Vec::with_capacity(4 * slices);
    for run in sorted.chunk_by(|a, b| slice_of(a.0) == slice_of(b.0)) {
        let mut keep = [0, 0, 0, run.len() - 1];
        for (i, p) in run.iter().enumerate() {
            if p.1 < run[keep[1]].1 {
                keep[1] = i;
            }
            if p.1 > run[keep[2]].1 {
                keep[2] = i;
            }
        }
        keep.sort_unstable();
        let mut previous = None;
        for i in keep {
            if previous != Some(i) {
                out.push(run[i]);
                previous = Some(i);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn few_points_stay_as_they_are_but_sorted() {
        let p = [(2.0, 1.0), (0.0, 5.0), (1.0, 3.0)];
        assert_eq!(envelope(&p, 10), vec![(0.0, 5.0), (1.0, 3.0), (2.0, 1.0)]);
    }

    #[test]
    fn many_points_keep_every_slice_extreme() {
        // A sine sampled 100 000 times, with one spike in the middle.
        let mut p: Vec<(f64, f64)> = (0..100_000)
            .map(|i| {
                let x = i as f64 * 1e-4;
                (x, (x * 6.0).sin())
            })
            .collect();
        p[50_000].1 = 7.0;
        let thin = envelope(&p, 500);
        assert!(thin.len() <= 2000, "{} points", thin.len());
        let max = thin.iter().map(|q| q.1).fold(f64::MIN, f64::max);
        let min = thin.iter().map(|q| q.1).fold(f64::MAX, f64::min);
        assert_eq!(max, 7.0);
        assert!(min < -0.9999, "{min}");
        assert_eq!(thin[0], p[0]);
        assert_eq!(thin[thin.len() - 1], p[p.len() - 1]);
        assert!(thin.windows(2).all(|w| w[0].0 <= w[1].0));
    }

    #[test]
    fn all_at_one_instant_is_one_slice() {
        let p: Vec<(f64, f64)> = (0..100).map(|i| (1.0, f64::from(i))).collect();
        assert_eq!(envelope(&p, 2), vec![(1.0, 0.0), (1.0, 99.0)]);
    }
}
