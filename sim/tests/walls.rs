//! Procedural worlds have walls shaped like the Unity terrain's: measured the same way on both
//! (every 0.5 m, against the distance from the flat floor), their heights, slopes and the way
//! they vary along a wall match the survey (`../shared/udacity-world/elevation_cm.png`).

use rover_sim::distance::distance_to;
use rover_sim::elevation::Elevation;
use rover_sim::procgen::procedural_world;

/// Spacing of the measuring grid, metres (the survey's).
const STEP_M: f64 = 0.5;
/// Points of the measuring grid a side.
const SIDE: usize = 401;
/// Ground below this height is the flat floor, metres.
const FLAT_BELOW_M: f64 = 0.05;
/// Bands of distance from the flat floor, metres, from the foot to high on the walls.
const BANDS_M: [(f64, f64); 7] = [(1.0, 1.5), (1.5, 2.0), (2.0, 3.0), (3.0, 4.0), (4.0, 6.0), (6.0, 8.0), (8.0, 12.0)];

/// Heights on the measuring grid, metres.
struct Ground {
    heights_m: Vec<f64>,
    distance_m: Vec<f64>,
}

impl Ground {
    fn measure(height_at: impl Fn(f64, f64) -> f64) -> Self {
        let heights_m: Vec<f64> =
            (0..SIDE * SIDE).map(|i| height_at((i % SIDE) as f64 * STEP_M, (i / SIDE) as f64 * STEP_M)).collect();
        let flat: Vec<bool> = heights_m.iter().map(|&h| h < FLAT_BELOW_M).collect();
        let distance_m = distance_to(&flat, SIDE).into_iter().map(|d| d as f64 * STEP_M).collect();
        Ground { heights_m, distance_m }
    }

    fn surveyed() -> Self {
        let path = format!("{}/../../shared/udacity-world/elevation_cm.png", env!("CARGO_MANIFEST_DIR"));
        let png = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let survey = Elevation::from_png(&png).unwrap();
        Ground::measure(|x, y| survey.height_at(x, y) as f64)
    }

    fn procedural(seed: u64) -> Self {
        let world = procedural_world(seed);
        Ground::measure(|x, y| world.terrain().height_at(x, y) as f64)
    }

    /// Grid points whose distance from the floor lies in `band`.
    fn in_band(&self, (near_m, far_m): (f64, f64)) -> impl Iterator<Item = usize> + '_ {
        (0..SIDE * SIDE).filter(move |&i| (near_m..far_m).contains(&self.distance_m[i]))
    }

    /// Steepest slope at an inner grid point, degrees (central differences).
    fn slope_deg(&self, i: usize) -> f64 {
        let (x, y) = (i % SIDE, i / SIDE);
        let (x0, x1, y0, y1) = (x.saturating_sub(1), (x + 1).min(SIDE - 1), y.saturating_sub(1), (y + 1).min(SIDE - 1));
        let h = |x: usize, y: usize| self.heights_m[y * SIDE + x];
        let dx = (h(x1, y) - h(x0, y)) / ((x1 - x0) as f64 * STEP_M);
        let dy = (h(x, y1) - h(x, y0)) / ((y1 - y0) as f64 * STEP_M);
        dx.hypot(dy).atan().to_degrees()
    }

    /// The 10th, 50th and 90th percentiles of height and the median slope in each band.
    fn profile(&self) -> Vec<([f64; 3], f64)> {
        BANDS_M
            .iter()
            .map(|&band| {
                let heights = percentiles(self.in_band(band).map(|i| self.heights_m[i]).collect());
                let slope = percentiles(self.in_band(band).map(|i| self.slope_deg(i)).collect())[1];
                (heights, slope)
            })
            .collect()
    }

    /// Correlation between the heights of two wall points 2.5-3.5 m from the floor, `lag_m`
    /// apart (within 20 %): how far along a wall its shape holds.
    fn correlation_at(&self, lag_m: f64) -> f64 {
        let points: Vec<usize> = self.in_band((2.5, 3.5)).step_by(7).collect();
        let xy = |i: usize| ((i % SIDE) as f64 * STEP_M, (i / SIDE) as f64 * STEP_M);
        let mean = points.iter().map(|&i| self.heights_m[i]).sum::<f64>() / points.len() as f64;
        let (mut product, mut square_a, mut square_b) = (0.0, 0.0, 0.0);
        for (n, &a) in points.iter().enumerate() {
            let (ax, ay) = xy(a);
            for &b in &points[n + 1..] {
                let (bx, by) = xy(b);
                if ((ax - bx).hypot(ay - by) - lag_m).abs() <= 0.2 * lag_m {
                    let (da, db) = (self.heights_m[a] - mean, self.heights_m[b] - mean);
                    product += da * db;
                    square_a += da * da;
                    square_b += db * db;
                }
            }
        }
        product / (square_a * square_b).sqrt()
    }
}

fn percentiles(mut values: Vec<f64>) -> [f64; 3] {
    assert!(!values.is_empty(), "a band with no points");
    values.sort_by(f64::total_cmp);
    let at = |p: f64| values[((values.len() - 1) as f64 * p).round() as usize];
    [at(0.1), at(0.5), at(0.9)]
}

#[test]
fn procedural_walls_rise_and_steepen_as_the_surveyed_walls_do() {
    let surveyed = Ground::surveyed().profile();
    for seed in [0, 1] {
        let procedural = Ground::procedural(seed).profile();
        for ((band, (real, real_slope)), (ours, our_slope)) in BANDS_M.iter().zip(&surveyed).zip(&procedural) {
            for (p, (r, o)) in ["p10", "median", "p90"].iter().zip(real.iter().zip(ours)) {
                assert!((o / r - 1.0).abs() <= 0.25, "seed {seed}, {band:?} m: {p} height {o:.2} m, survey {r:.2}");
            }
            assert!(
                (our_slope - real_slope).abs() <= 10.0,
                "seed {seed}, {band:?} m: slope {our_slope:.0}, survey {real_slope:.0}"
            );
        }
    }
}

#[test]
fn procedural_walls_vary_along_their_length_over_the_surveyed_distances() {
    let surveyed = Ground::surveyed();
    let procedural = Ground::procedural(2);
    for lag_m in [2.0, 4.0, 8.0, 16.0] {
        let (real, ours) = (surveyed.correlation_at(lag_m), procedural.correlation_at(lag_m));
        assert!((ours - real).abs() <= 0.2, "{lag_m} m along a wall: correlation {ours:.2}, survey {real:.2}");
    }
    assert!(
        surveyed.correlation_at(2.0) > 0.5 && surveyed.correlation_at(16.0) < 0.2,
        "the survey's walls change over metres"
    );
}
