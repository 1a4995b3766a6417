//! The shadows the terrain and the surveyed rocks cast on the terrain, baked once per world: a
//! node is in shadow when something stands between it and the sun.

use nalgebra::Vector3;

use crate::terrain::{MAX_TERRAIN_HEIGHT_M, NODES_PER_M, TERRAIN_STEP_M};
use crate::world::{WORLD_SIZE, World};

/// A ray towards the sun is followed in steps of this length, metres.
const STEP_M: f64 = TERRAIN_STEP_M;
/// Over this height below the ray the shadow fades in, metres: its edge is soft.
const PENUMBRA_M: f64 = 0.1;

/// How much each terrain node is in shadow, 0 (lit) to 1, row by row.
pub(super) fn node_shadows(world: &World, sun: &Vector3<f64>) -> Vec<f32> {
    let side = WORLD_SIZE * NODES_PER_M;
    let horizontal = sun.x.hypot(sun.y);
    if sun.z <= 0.0 || horizontal < 1e-9 {
        return vec![if sun.z <= 0.0 { 1.0 } else { 0.0 }; side * side];
    }
    let (dx, dy, rise) = (sun.x / horizontal * STEP_M, sun.y / horizontal * STEP_M, sun.z / horizontal * STEP_M);
    let steps = (MAX_TERRAIN_HEIGHT_M as f64 / rise).ceil() as usize + 1;
    let terrain = world.terrain();
    (0..side * side)
        .map(|i| {
            let (x, y) = (((i % side) as f64 + 0.5) * TERRAIN_STEP_M, ((i / side) as f64 + 0.5) * TERRAIN_STEP_M);
            let start = terrain.height_at(x, y) as f64;
            let mut shadow = 0.0f64;
            for k in 1..=steps {
                let (px, py, pz) = (x + dx * k as f64, y + dy * k as f64, start + rise * k as f64);
                let above = highest_at(world, px, py, pz) - pz;
                shadow = shadow.max(((above + PENUMBRA_M / 2.0) / PENUMBRA_M).clamp(0.0, 1.0));
                if shadow >= 1.0 || pz > MAX_TERRAIN_HEIGHT_M as f64 {
                    break;
                }
            }
            shadow as f32
        })
        .collect()
}

/// The highest solid at (x, y) that reaches up to height `z` or above it: the terrain, or a
/// surveyed rock whose column spans `z`.
fn highest_at(world: &World, x_m: f64, y_m: f64, z_m: f64) -> f64 {
    let ground = world.terrain().height_at(x_m, y_m) as f64;
    let rock = world
        .surveyed_rocks()
        .iter()
        .filter_map(|rock| rock.column_at(x_m, y_m))
        .filter(|column| (column.bottom_m as f64) <= z_m)
        .map(|column| column.top_m as f64)
        .fold(f64::MIN, f64::max);
    ground.max(rock)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::{StartPose, rectangle};

    #[test]
    fn the_floor_at_the_foot_of_a_wall_between_it_and_the_sun_is_in_shadow() {
        let corridor = rectangle(50..150, 95..105);
        let world = World::open(corridor, StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 });
        let sun = Vector3::new(0.321, -0.557, 0.766);
        let shadows = node_shadows(&world, &sun);
        let at = |x: f64, y: f64| {
            let side = WORLD_SIZE * NODES_PER_M;
            shadows[(y / TERRAIN_STEP_M) as usize * side + (x / TERRAIN_STEP_M) as usize]
        };
        assert_eq!(at(100.1, 95.2), 1.0, "the south wall stands between the sun and its foot");
        assert_eq!(at(100.1, 104.8), 0.0, "the north wall's foot faces the sun");
        assert!(node_shadows(&world, &Vector3::z()).iter().all(|&s| s == 0.0), "the sun overhead casts none");
    }
}
