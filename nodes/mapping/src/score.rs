//! The Udacity scores, exactly as the starter's `create_output_images` computes them
//! (unity-sim-spec 6.2): mapped % and fidelity % of a world map against the ground truth, and
//! which samples count as located.

use rover_msgs::map_grid::{OCCUPANCY_FREE, OCCUPANCY_OCCUPIED, SIDE_CELLS};

/// Mapped and fidelity percentages, rounded to one decimal like the starter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Scores {
    /// 100 * good navigable cells / ground-truth navigable cells.
    pub mapped_pct: f64,
    /// 100 * good navigable cells / navigable cells of the map (0 when there are none).
    pub fidelity_pct: f64,
    /// Navigable cells of the map that are navigable in the ground truth.
    pub good_cells: usize,
    /// Navigable cells of the map.
    pub navigable_cells: usize,
}

/// Scores an occupancy grid (row = y) like a Udacity world map: its navigable channel is 255 on
/// the free cells and 0 elsewhere, which the starter's normalisation by the mean of the non-zero
/// cells leaves as it is, so the scores are counts of cells.
pub fn occupancy_scores(occupancy: &[i8], ground_truth: &[bool]) -> Scores {
    let free = || occupancy.iter().map(|&v| v == OCCUPANCY_FREE);
    let navigable_cells = free().filter(|&f| f).count();
    let good_cells = free().zip(ground_truth).filter(|&(f, &truth)| f && truth).count();
    scores_of_counts(good_cells, navigable_cells, ground_truth)
}

/// The scores of a map with `navigable_cells` navigable cells, `good_cells` of them navigable in
/// `ground_truth`, rounded to one decimal like the starter.
fn scores_of_counts(good_cells: usize, navigable_cells: usize, ground_truth: &[bool]) -> Scores {
    let truth = ground_truth.iter().filter(|&&g| g).count();
    let round1 = |v: f64| (v * 10.0).round() / 10.0;
    let percent = |part: usize, whole: usize| if whole > 0 { round1(100.0 * part as f64 / whole as f64) } else { 0.0 };
    Scores {
        mapped_pct: percent(good_cells, truth),
        fidelity_pct: percent(good_cells, navigable_cells),
        good_cells,
        navigable_cells,
    }
}

/// Counts of the navigable and the obstacle cells of an occupancy grid.
pub fn occupancy_counts(occupancy: &[i8]) -> (usize, usize) {
    let count = |value: i8| occupancy.iter().filter(|&&v| v == value).count();
    (count(OCCUPANCY_FREE), count(OCCUPANCY_OCCUPIED))
}

/// Samples counted as located: a rock cell (x, y) lies within 3 cells of the sample's truncated
/// position. As in the starter, nothing is located when every rock cell is in row 0.
pub fn samples_located(rock_cells: &[(usize, usize)], samples: &[(f64, f64)]) -> usize {
    samples.iter().filter(|&&sample| is_located(rock_cells, sample)).count()
}

fn is_located(rock_cells: &[(usize, usize)], (sx, sy): (f64, f64)) -> bool {
    if !rock_cells.iter().any(|&(_, y)| y != 0) {
        return false;
    }
    let (sx, sy) = (sx as i64 as f64, sy as i64 as f64);
    rock_cells.iter().any(|&(x, y)| (x as f64 - sx).hypot(y as f64 - sy) < 3.0)
}

/// The samples located at any time of a run, by the rule of [`samples_located`]: a collected
/// sample leaves the map but stays counted.
#[derive(Debug, Clone, Default)]
pub struct LocatedSamples {
    samples: Vec<(f64, f64)>,
    located: Vec<bool>,
}

impl LocatedSamples {
    /// Tracks the samples at `samples` (world metres).
    pub fn new(samples: Vec<(f64, f64)>) -> Self {
        let located = vec![false; samples.len()];
        LocatedSamples { samples, located }
    }

    /// Marks the samples the rock cells `rock_cells` locate now.
    pub fn update(&mut self, rock_cells: &[(usize, usize)]) {
        for (flag, &sample) in self.located.iter_mut().zip(&self.samples) {
            *flag |= is_located(rock_cells, sample);
        }
    }

    /// How many were ever located.
    pub fn count(&self) -> usize {
        self.located.iter().filter(|&&l| l).count()
    }
}

/// The ground-truth navigable mask of a PNG of one pixel per map cell (pixel > 0 is navigable).
pub fn ground_truth_from_png(png: &[u8]) -> Result<Vec<bool>, String> {
    let image = rover_imaging::decode_png(png).map_err(|e| e.to_string())?;
    if (image.width, image.height) != (SIDE_CELLS, SIDE_CELLS) {
        return Err(format!("ground truth is {}x{}, expected {SIDE_CELLS}x{SIDE_CELLS}", image.width, image.height));
    }
    Ok(image.data.chunks_exact(3).map(|p| p[1] > 0).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The starter's `create_output_images` scoring of a world map given as its obstacle and
    /// navigable channels: each channel scaled so that the mean of its non-zero cells is 255,
    /// obstacle cleared where navigable is as strong, navigable clipped to 0..255, then counted.
    fn starter_scores(obstacle: &[f32], navigable: &[f32], ground_truth: &[bool]) -> Scores {
        let normalised = |channel: &[f32]| {
            let positive: Vec<f64> = channel.iter().filter(|&&v| v > 0.0).map(|&v| v as f64).collect();
            if positive.is_empty() {
                return channel.to_vec();
            }
            let mean = positive.iter().sum::<f64>() / positive.len() as f64;
            channel.iter().map(|&v| (v as f64 * 255.0 / mean) as f32).collect::<Vec<f32>>()
        };
        let nav = normalised(navigable);
        let mut obs = normalised(obstacle);
        for (o, n) in obs.iter_mut().zip(&nav) {
            if *n >= *o {
                *o = 0.0;
            }
        }
        let plot_nav: Vec<f32> = nav.iter().map(|v| v.clamp(0.0, 255.0)).collect();
        let navigable_cells = plot_nav.iter().filter(|&&v| v != 0.0).count();
        let good_cells = plot_nav.iter().zip(ground_truth).filter(|(v, gt)| **v > 0.0 && **gt).count();
        scores_of_counts(good_cells, navigable_cells, ground_truth)
    }

    #[test]
    fn occupancy_grids_score_their_free_cells() {
        let occupancy = [0i8, 0, 100, -1];
        let scores = occupancy_scores(&occupancy, &[true, false, true, true]);
        assert_eq!((scores.good_cells, scores.navigable_cells), (1, 2));
        assert_eq!((scores.mapped_pct, scores.fidelity_pct), (33.3, 50.0));
        assert_eq!(occupancy_counts(&occupancy), (2, 1));
    }

    #[test]
    fn empty_maps_score_zero() {
        let scores = occupancy_scores(&[-1; 4], &[true; 4]);
        assert_eq!((scores.mapped_pct, scores.fidelity_pct), (0.0, 0.0));
    }

    proptest::proptest! {
        #[test]
        fn occupancy_scores_are_the_starters_scores_of_its_channels(
            cells in proptest::collection::vec((proptest::sample::select(vec![-1i8, 0, 100]), proptest::bool::ANY), 1..400)
        ) {
            let (occupancy, truth): (Vec<i8>, Vec<bool>) = cells.into_iter().unzip();
            let channel = |value: i8| occupancy.iter().map(|&v| if v == value { 255.0 } else { 0.0 }).collect::<Vec<f32>>();
            proptest::prop_assert_eq!(
                occupancy_scores(&occupancy, &truth),
                starter_scores(&channel(OCCUPANCY_OCCUPIED), &channel(OCCUPANCY_FREE), &truth)
            );
        }
    }

    #[test]
    fn located_samples_need_a_rock_cell_within_three() {
        let samples = [(97.44, 74.65), (122.28, 51.66)];
        assert_eq!(samples_located(&[(98, 76)], &samples), 1);
        assert_eq!(samples_located(&[(100, 74)], &samples), 0);
        assert_eq!(samples_located(&[(97, 0)], &[(97.5, 0.5)]), 0, "row-0 quirk");
    }

    #[test]
    fn located_samples_stay_counted_after_their_rock_is_gone() {
        let mut located = LocatedSamples::new(vec![(97.44, 74.65), (122.28, 51.66)]);
        located.update(&[(98, 76)]);
        located.update(&[]);
        assert_eq!(located.count(), 1);
        located.update(&[(121, 52), (40, 40)]);
        assert_eq!(located.count(), 2);
    }
}
