//! Located rock samples: rock cells grouped into rocks, each placed where it was seen from closest.

/// A map cell holding rock evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RockCell {
    /// Column (x), metres from the map origin.
    pub x: usize,
    /// Row (y), metres from the map origin.
    pub y: usize,
    /// The shortest range the rock in this cell was seen from, metres.
    pub range_m: f32,
}

impl RockCell {
    fn centre(&self) -> (f64, f64) {
        (self.x as f64 + 0.5, self.y as f64 + 0.5)
    }
}

/// Rock positions (x, y), metres. Cells are taken from the one seen from closest on: a cell within
/// `merge_m` of a rock already placed belongs to it, any other places a new rock. A sample seen
/// from afar lands beyond where it lies (it stands above the floor, often on the foot of a wall),
/// so the closest sighting is the best estimate and the farther ones are its echoes.
pub(crate) fn rock_positions(cells: &[RockCell], merge_m: f64) -> Vec<(f64, f64)> {
    let mut by_range = cells.to_vec();
    by_range.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    let mut rocks: Vec<(f64, f64)> = Vec::new();
    for cell in &by_range {
        let (cx, cy) = cell.centre();
        if !rocks.iter().any(|&(x, y)| (x - cx).hypot(y - cy) < merge_m) {
            rocks.push((cx, cy));
        }
    }
    rocks
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(x: usize, y: usize, range_m: f32) -> RockCell {
        RockCell { x, y, range_m }
    }

    #[test]
    fn a_rock_is_where_it_was_seen_from_closest_and_distant_rocks_stay_apart() {
        let cells = [cell(13, 10, 6.0), cell(10, 10, 1.5), cell(11, 10, 3.0), cell(40, 40, 4.0)];
        let rocks = rock_positions(&cells, 3.5);
        assert_eq!(rocks, vec![(10.5, 10.5), (40.5, 40.5)]);
        assert_eq!(rock_positions(&cells, 2.0).len(), 3, "an echo beyond the merge distance is a rock of its own");
        assert!(rock_positions(&[], 2.0).is_empty());
    }
}
