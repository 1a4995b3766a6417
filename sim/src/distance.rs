//! Exact Euclidean distance transform on a square grid (Felzenszwalb and Huttenlocher's two-pass
//! lower envelope of parabolas), used to shape the walls by their distance from the floor.

/// Distance, in grid steps, from every node of a `side` x `side` grid to the nearest node where
/// `source` is true; `f32::INFINITY` everywhere when there is no source.
pub fn distance_to(source: &[bool], side: usize) -> Vec<f32> {
    assert_eq!(source.len(), side * side, "the source mask must be side x side");
    let mut squared: Vec<f64> = source.iter().map(|&s| if s { 0.0 } else { f64::INFINITY }).collect();
    let mut line = vec![0.0; side];
    let mut out = vec![0.0; side];
    let mut scratch = Envelope::new(side);
    for x in 0..side {
        (0..side).for_each(|y| line[y] = squared[y * side + x]);
        scratch.transform(&line, &mut out);
        (0..side).for_each(|y| squared[y * side + x] = out[y]);
    }
    for y in 0..side {
        let row = &mut squared[y * side..(y + 1) * side];
        line.copy_from_slice(row);
        scratch.transform(&line, &mut out);
        row.copy_from_slice(&out);
    }
    squared.iter().map(|&d| d.sqrt() as f32).collect()
}

/// Work space of the one-dimensional transform.
struct Envelope {
    vertices: Vec<usize>,
    boundaries: Vec<f64>,
}

impl Envelope {
    fn new(side: usize) -> Self {
        Envelope { vertices: vec![0; side], boundaries: vec![0.0; side + 1] }
    }

    /// `out[q]` = min over p of `f[p] + (q - p)^2`.
    fn transform(&mut self, f: &[f64], out: &mut [f64]) {
        let Some(first) = f.iter().position(|v| v.is_finite()) else {
            out.fill(f64::INFINITY);
            return;
        };
        let (v, z) = (&mut self.vertices, &mut self.boundaries);
        let mut k = 0;
        v[0] = first;
        z[0] = f64::NEG_INFINITY;
        z[1] = f64::INFINITY;
        for q in first + 1..f.len() {
            if !f[q].is_finite() {
                continue;
            }
            let intersection = |p: usize| ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
            let mut s = intersection(v[k]);
            while s <= z[k] {
                k -= 1;
                s = intersection(v[k]);
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
        }
        k = 0;
        for (q, value) in out.iter_mut().enumerate() {
            while z[k + 1] < q as f64 {
                k += 1;
            }
            let d = q as f64 - v[k] as f64;
            *value = d * d + f[v[k]];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute_force(source: &[bool], side: usize) -> Vec<f32> {
        (0..side * side)
            .map(|i| {
                let (x, y) = ((i % side) as f64, (i / side) as f64);
                (0..side * side)
                    .filter(|&j| source[j])
                    .map(|j| ((j % side) as f64 - x).hypot((j / side) as f64 - y))
                    .fold(f64::INFINITY, f64::min) as f32
            })
            .collect()
    }

    #[test]
    fn one_source_gives_the_euclidean_distance() {
        let mut source = vec![false; 25];
        source[12] = true;
        let d = distance_to(&source, 5);
        assert_eq!(d[12], 0.0);
        assert!((d[0] - 8f32.sqrt()).abs() < 1e-6);
        assert_eq!(d[14], 2.0);
        assert!(distance_to(&[false; 9], 3).iter().all(|v| v.is_infinite()));
    }

    proptest! {
        #[test]
        fn matches_brute_force(cells in proptest::collection::vec(proptest::bool::weighted(0.1), 144)) {
            let fast = distance_to(&cells, 12);
            let slow = brute_force(&cells, 12);
            for (a, b) in fast.iter().zip(&slow) {
                prop_assert!((a - b).abs() < 1e-5 || (a.is_infinite() && b.is_infinite()), "{a} vs {b}");
            }
        }
    }
}
