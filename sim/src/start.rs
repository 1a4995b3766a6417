//! Where the rover starts: the world's own start, a pose the user gives, or a seeded random pose
//! on the floor the rover can reach from the world's start, facing anywhere. Wherever it starts
//! is home.

use std::str::FromStr;

use crate::random::{SplitMix64, mix64};
use crate::world::{StartPose, WORLD_SIZE, World, cell_centre, reached_from};

/// Every 1 m cell within this many cells of a random start is drivable all over: the rover does
/// not start touching a wall or a rock.
const CLEARANCE_CELLS: i64 = 1;
/// A random start is at least this far from every sample, metres, so that no mission starts with
/// a sample under the arm.
const MIN_SAMPLE_DISTANCE_M: f64 = 2.0;
/// Keeps the random start's draws apart from the world's own, which use the same seed.
const RANDOM_START_SALT: u64 = 0x5354_4152_5421;

/// Why a start cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StartError {
    /// The text is not `X,Y,YAW`.
    #[error("start '{0}': expected X,Y,YAW (metres, metres, degrees counter-clockwise from +x), e.g. 60.5,100.5,180")]
    Malformed(String),
    /// The pose is not on ground the rover can drive.
    #[error("start ({x_m}, {y_m}) is not drivable ground of this world")]
    NotDrivable {
        /// x, metres.
        x_m: f64,
        /// y, metres.
        y_m: f64,
    },
    /// The world has no floor for a random start.
    #[error("no floor reachable from the world's start leaves room for a random start")]
    NoRoom,
}

impl FromStr for StartPose {
    type Err = StartError;

    /// Reads `X,Y,YAW`: metres, metres, degrees counter-clockwise from +x.
    fn from_str(text: &str) -> Result<Self, StartError> {
        let malformed = || StartError::Malformed(text.to_string());
        let values = text.split(',').map(|v| v.trim().parse::<f64>()).collect::<Result<Vec<_>, _>>();
        match values.map_err(|_| malformed())?.as_slice() {
            &[x_m, y_m, yaw_deg] if [x_m, y_m, yaw_deg].iter().all(|v| v.is_finite()) => {
                Ok(StartPose { x_m, y_m, yaw_deg })
            }
            _ => Err(malformed()),
        }
    }
}

/// `world` with the rover starting at `start`, which must be drivable.
pub(crate) fn starting_at(mut world: World, start: StartPose) -> Result<World, StartError> {
    if !world.is_drivable(start.x_m, start.y_m) {
        return Err(StartError::NotDrivable { x_m: start.x_m, y_m: start.y_m });
    }
    world.start = start;
    Ok(world)
}

/// A start drawn for `seed`: the centre of a cell reachable from the world's start with room all
/// around and no sample near, and a heading drawn from the full circle.
pub(crate) fn random_start(world: &World, seed: u64) -> Result<StartPose, StartError> {
    let drivable = world.drivable_cells();
    let reachable = reached_from(&drivable, cell_of(world.start.x_m, world.start.y_m));
    let candidates: Vec<usize> = (0..drivable.len())
        .filter(|&cell| reachable[cell] && has_room_around(&drivable, cell) && far_from_samples(world, cell))
        .collect();
    if candidates.is_empty() {
        return Err(StartError::NoRoom);
    }
    let mut rng = SplitMix64::new(mix64(seed ^ RANDOM_START_SALT));
    let cell = candidates[rng.below(candidates.len())];
    let (x_m, y_m) = cell_centre(cell);
    Ok(StartPose { x_m, y_m, yaw_deg: rng.range(0.0, 360.0) })
}

fn cell_of(x_m: f64, y_m: f64) -> usize {
    let clamp = |v: f64| (v.max(0.0) as usize).min(WORLD_SIZE - 1);
    clamp(y_m) * WORLD_SIZE + clamp(x_m)
}

fn has_room_around(drivable: &[bool], cell: usize) -> bool {
    let (x, y) = ((cell % WORLD_SIZE) as i64, (cell / WORLD_SIZE) as i64);
    let range = -CLEARANCE_CELLS..=CLEARANCE_CELLS;
    let on_map = |v: i64| (0..WORLD_SIZE as i64).contains(&v);
    range.clone().all(|dy| {
        range.clone().all(|dx| {
            let (nx, ny) = (x + dx, y + dy);
            on_map(nx) && on_map(ny) && drivable[ny as usize * WORLD_SIZE + nx as usize]
        })
    })
}

fn far_from_samples(world: &World, cell: usize) -> bool {
    let (x_m, y_m) = cell_centre(cell);
    world.samples.iter().all(|s| (s.x_m - x_m).hypot(s.y_m - y_m) >= MIN_SAMPLE_DISTANCE_M)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::rectangle;

    fn two_rooms() -> World {
        let mut floor = rectangle(20..40, 20..40);
        let far_room = rectangle(100..120, 100..120);
        floor.iter_mut().zip(far_room).for_each(|(cell, far)| *cell |= far);
        World::open(floor, StartPose { x_m: 30.5, y_m: 30.5, yaw_deg: 0.0 })
    }

    #[test]
    fn a_start_is_read_as_x_y_and_yaw() {
        let start: StartPose = " 60.5, 100.5 ,-90".parse().unwrap();
        assert_eq!(start, StartPose { x_m: 60.5, y_m: 100.5, yaw_deg: -90.0 });
    }

    #[test]
    fn a_start_without_three_finite_numbers_is_refused_naming_it() {
        for text in ["60,100", "60,100,0,1", "a,b,c", "60,NaN,0", ""] {
            let error = text.parse::<StartPose>().unwrap_err();
            assert_eq!(error, StartError::Malformed(text.to_string()));
            assert!(error.to_string().contains("expected X,Y,YAW"), "{error}");
        }
    }

    #[test]
    fn a_given_start_must_be_drivable() {
        let inside = StartPose { x_m: 25.0, y_m: 35.0, yaw_deg: 90.0 };
        assert_eq!(starting_at(two_rooms(), inside).unwrap().start, inside);
        let outside = StartPose { x_m: 60.0, y_m: 60.0, yaw_deg: 0.0 };
        assert_eq!(starting_at(two_rooms(), outside).unwrap_err(), StartError::NotDrivable { x_m: 60.0, y_m: 60.0 });
    }

    #[test]
    fn random_starts_stay_in_the_reachable_room_off_its_walls_and_face_every_way() {
        let world = two_rooms();
        let starts: Vec<StartPose> = (0..200).map(|seed| random_start(&world, seed).unwrap()).collect();
        for start in &starts {
            assert!((21.0..39.0).contains(&start.x_m) && (21.0..39.0).contains(&start.y_m), "{start:?}");
        }
        let headings = |lo: f64, hi: f64| starts.iter().filter(|s| (lo..hi).contains(&s.yaw_deg)).count();
        assert!((0..4).all(|quarter| headings(quarter as f64 * 90.0, (quarter + 1) as f64 * 90.0) > 20));
        assert_eq!(random_start(&world, 7), random_start(&world, 7));
        assert_ne!(random_start(&world, 7), random_start(&world, 8));
    }

    #[test]
    fn a_world_too_narrow_for_room_around_has_no_random_start() {
        let corridor = World::open(rectangle(20..120, 50..51), StartPose { x_m: 30.5, y_m: 50.5, yaw_deg: 0.0 });
        assert_eq!(random_start(&corridor, 0), Err(StartError::NoRoom));
    }
}
