//! The surveyed rock obstacles of the Unity world: `rocks.json` (`../shared/udacity-world/README.md`
//! section 4) gives, for each rock, a grid of cells with the lowest and highest height of its
//! surface above each, so a rock is a column of solid rock over every cell it covers, raised off
//! the floor where it overhangs.

use serde::Deserialize;

use crate::obstacle::{CLEARANCE_M, Obstacle};
use crate::world::WorldError;

/// Most rocks a survey may hold.
const MAX_ROCKS: usize = 1024;
/// Most cells a side of one rock's grid.
const MAX_GRID_SIDE: usize = 1024;
/// Cell sizes a survey may use, metres.
const CELL_RANGE_M: std::ops::RangeInclusive<f64> = 0.05..=2.0;
/// Origins a survey may give, metres: around the world.
const COORDINATE_RANGE_M: std::ops::RangeInclusive<f64> = -100.0..=300.0;
/// Heights a survey may give, metres above the floor (parts below it are dropped).
const HEIGHT_RANGE_M: std::ops::RangeInclusive<f64> = 0.0..=300.0;

/// The rock over one cell: solid from `bottom_m` to `top_m` above the floor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RockColumn {
    /// Lowest surface, metres above the floor.
    pub bottom_m: f32,
    /// Highest surface, metres above the floor.
    pub top_m: f32,
}

/// One surveyed rock: columns of rock over a grid of square cells.
#[derive(Debug, Clone, PartialEq)]
pub struct SurveyedRock {
    /// The grid's south-west corner (x, y), metres.
    pub origin_m: [f64; 2],
    /// Side of a cell, metres.
    pub cell_m: f64,
    /// Cells along x.
    pub cols: usize,
    /// Cells along y.
    pub rows: usize,
    /// Row by row from the south, `None` where there is no rock.
    pub columns: Vec<Option<RockColumn>>,
}

impl SurveyedRock {
    /// The column over (x, y), if the rock covers that point.
    pub fn column_at(&self, x_m: f64, y_m: f64) -> Option<RockColumn> {
        let (gx, gy) = ((x_m - self.origin_m[0]) / self.cell_m, (y_m - self.origin_m[1]) / self.cell_m);
        if gx < 0.0 || gy < 0.0 || gx >= self.cols as f64 || gy >= self.rows as f64 {
            return None;
        }
        self.columns[gy as usize * self.cols + gx as usize]
    }

    /// The column of grid cell (column `c`, row `r`), none outside the grid.
    pub fn column(&self, c: i64, r: i64) -> Option<RockColumn> {
        if c < 0 || r < 0 || c >= self.cols as i64 || r >= self.rows as i64 {
            return None;
        }
        self.columns[r as usize * self.cols + c as usize]
    }

    /// The highest top of the rock, metres.
    pub fn highest_m(&self) -> f64 {
        self.columns.iter().flatten().map(|c| c.top_m as f64).fold(0.0, f64::max)
    }
}

impl Obstacle for SurveyedRock {
    fn covers(&self, x_m: f64, y_m: f64, ground_m: f64, up_to_m: f64) -> bool {
        self.column_at(x_m, y_m)
            .is_some_and(|c| (c.bottom_m as f64) < ground_m + up_to_m && c.top_m as f64 > ground_m + CLEARANCE_M)
    }

    fn bounds_m(&self) -> [[f64; 2]; 2] {
        let [x, y] = self.origin_m;
        [[x, y], [x + self.cols as f64 * self.cell_m, y + self.rows as f64 * self.cell_m]]
    }
}

/// The file as written: only the fields the simulator uses.
#[derive(Deserialize)]
struct SurveyFile {
    rocks: Vec<RockEntry>,
}

#[derive(Deserialize)]
struct RockEntry {
    cell_m: f64,
    origin: [f64; 2],
    rows: usize,
    cols: usize,
    bottom_m: Vec<Vec<Option<f64>>>,
    top_m: Vec<Vec<Option<f64>>>,
}

/// Reads a rock survey (`rocks.json`).
pub(crate) fn read_rock_survey(json: &[u8]) -> Result<Vec<SurveyedRock>, WorldError> {
    let invalid = |reason: String| WorldError::Unreadable { name: "rock survey", reason };
    let file: SurveyFile = serde_json::from_slice(json).map_err(|e| invalid(e.to_string()))?;
    if file.rocks.len() > MAX_ROCKS {
        return Err(invalid(format!("{} rocks, at most {MAX_ROCKS} expected", file.rocks.len())));
    }
    file.rocks
        .iter()
        .enumerate()
        .map(|(i, rock)| surveyed_rock(rock).map_err(|e| invalid(format!("rock {i}: {e}"))))
        .collect()
}

/// One rock of the file, checked.
fn surveyed_rock(rock: &RockEntry) -> Result<SurveyedRock, String> {
    if !CELL_RANGE_M.contains(&rock.cell_m) {
        return Err(format!("cell_m {} is not in {CELL_RANGE_M:?} m", rock.cell_m));
    }
    if !rock.origin.iter().all(|c| COORDINATE_RANGE_M.contains(c)) {
        return Err(format!("origin {:?} is not in {COORDINATE_RANGE_M:?} m", rock.origin));
    }
    if rock.rows == 0 || rock.cols == 0 || rock.rows > MAX_GRID_SIDE || rock.cols > MAX_GRID_SIDE {
        return Err(format!("grid of {} x {} cells, expected 1 to {MAX_GRID_SIDE} a side", rock.rows, rock.cols));
    }
    let grid_fits =
        |grid: &[Vec<Option<f64>>]| grid.len() == rock.rows && grid.iter().all(|row| row.len() == rock.cols);
    if !grid_fits(&rock.bottom_m) || !grid_fits(&rock.top_m) {
        return Err(format!("bottom_m and top_m must be {} rows of {} cells", rock.rows, rock.cols));
    }
    let cells = rock.bottom_m.iter().flatten().zip(rock.top_m.iter().flatten());
    let columns = cells
        .enumerate()
        .map(|(i, (&bottom, &top))| match (bottom, top) {
            (None, None) => Ok(None),
            (Some(bottom_m), Some(top_m))
                if HEIGHT_RANGE_M.contains(&bottom_m) && HEIGHT_RANGE_M.contains(&top_m) && bottom_m <= top_m =>
            {
                Ok(Some(RockColumn { bottom_m: bottom_m as f32, top_m: top_m as f32 }))
            }
            _ => Err(format!(
                "cell (row {}, column {}) has bottom {bottom:?} and top {top:?}: expected both null, or heights in \
                 {HEIGHT_RANGE_M:?} m with the bottom not above the top",
                i / rock.cols,
                i % rock.cols
            )),
        })
        .collect::<Result<_, _>>()?;
    Ok(SurveyedRock { origin_m: rock.origin, cell_m: rock.cell_m, cols: rock.cols, rows: rock.rows, columns })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A survey of one rock at `origin`: a 2 x 3 grid of 0.5 m cells, raised over its east column.
    pub(crate) fn one_rock_json(origin: [f64; 2]) -> String {
        format!(
            r#"{{"description": "test", "rocks": [{{"x": 1, "cell_m": 0.5, "origin": [{}, {}], "rows": 2, "cols": 3,
               "bottom_m": [[0.0, 0.0, 1.0], [null, 0.0, 1.0]], "top_m": [[0.5, 1.5, 2.0], [null, 1.0, 2.0]]}}]}}"#,
            origin[0], origin[1]
        )
    }

    #[test]
    fn columns_are_found_by_position_and_cover_what_they_span() {
        let rocks = read_rock_survey(one_rock_json([10.0, 20.0]).as_bytes()).unwrap();
        let rock = &rocks[0];
        assert_eq!(rock.column_at(10.6, 20.1), Some(RockColumn { bottom_m: 0.0, top_m: 1.5 }));
        assert_eq!(rock.column_at(10.1, 20.6), None, "no rock in that cell");
        assert_eq!(rock.column_at(9.9, 20.1), None, "outside the grid");
        assert!(rock.covers(10.6, 20.1, 0.0, 0.55));
        assert!(!rock.covers(11.1, 20.1, 0.0, 0.55), "the rover passes under the raised column");
        assert!(rock.covers(11.1, 20.1, 0.0, 8.0));
        assert_eq!(rock.bounds_m(), [[10.0, 20.0], [11.5, 21.0]]);
        assert_eq!(rock.highest_m(), 2.0);
    }

    #[test]
    fn a_bad_survey_is_refused_naming_the_rock_and_what_was_wrong() {
        let error = |json: &str| read_rock_survey(json.as_bytes()).unwrap_err().to_string();
        assert!(error("not json").contains("rock survey"));
        let valid = one_rock_json([10.0, 20.0]);
        let text = error(&valid.replace("[null, 0.0, 1.0]", "[0.0, 1.0]"));
        assert!(text.contains("rock 0") && text.contains("2 rows of 3 cells"), "{text}");
        let text = error(&valid.replace("[0.0, 0.0, 1.0]", "[0.0, 0.0, 3.0]"));
        assert!(text.contains("row 0, column 2") && text.contains("not above the top"), "{text}");
        let text = error(&valid.replace("[0.5, 1.5, 2.0]", "[null, 1.5, 2.0]"));
        assert!(text.contains("row 0, column 0"), "{text}");
        let text = error(&valid.replace("\"cell_m\": 0.5", "\"cell_m\": 0.0"));
        assert!(text.contains("cell_m 0"), "{text}");
        let text = error(&valid.replace("\"rows\": 2", "\"rows\": 2000"));
        assert!(text.contains("2000 x 3"), "{text}");
    }

    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_text;

        use super::*;

        proptest! {
            #[test]
            fn fuzz_rock_survey_mutated_json(text in mutated_text(vec![one_rock_json([10.0, 20.0])])) {
                if let Ok(rocks) = read_rock_survey(text.as_bytes()) {
                    for rock in rocks {
                        prop_assert_eq!(rock.columns.len(), rock.rows * rock.cols);
                        prop_assert!(rock.columns.iter().flatten().all(|c| c.bottom_m <= c.top_m));
                    }
                }
            }
        }
    }
}
