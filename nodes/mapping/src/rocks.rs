//! Located rock samples: clusters of rock cells, merged when closer than a sample's spacing.

/// Rock positions (x, y), metres: the centres of 8-connected clusters of `cells` (x, y), merged
/// when closer than `merge_m`.
pub fn rock_positions(cells: &[(usize, usize)], merge_m: f64) -> Vec<(f64, f64)> {
    let mut clusters: Vec<(f64, f64, f64)> = Vec::new();
    for &(x, y) in cells {
        let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
        match clusters.iter_mut().find(|(sx, sy, n)| (sx / n - cx).hypot(sy / n - cy) < merge_m) {
            Some(cluster) => {
                cluster.0 += cx;
                cluster.1 += cy;
                cluster.2 += 1.0;
            }
            None => clusters.push((cx, cy, 1.0)),
        }
    }
    clusters.iter().map(|(sx, sy, n)| (sx / n, sy / n)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearby_cells_merge_and_distant_ones_do_not() {
        let positions = rock_positions(&[(10, 10), (11, 10), (10, 11), (40, 40)], 2.0);
        assert_eq!(positions.len(), 2);
        assert!((positions[0].0 - 10.833).abs() < 0.01 && (positions[0].1 - 10.833).abs() < 0.01, "{positions:?}");
        assert_eq!(positions[1], (40.5, 40.5));
        assert!(rock_positions(&[], 2.0).is_empty());
    }
}
