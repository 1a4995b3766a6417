//! The shadows the terrain and the surveyed rocks cast on the terrain, baked once per world: a
//! node is in shadow when something stands between it and the sun.

use nalgebra::Vector3;

use crate::terrain::{NODES_PER_M, TERRAIN_STEP_M};
use crate::world::{WORLD_SIZE, World};

/// A ray towards the sun is followed in steps of this length, metres.
const STEP_M: f64 = TERRAIN_STEP_M;
/// Over this height below the ray the shadow fades in, metres: its edge is soft.
const PENUMBRA_M: f64 = 0.1;
/// Side of the blocks whose highest solid lets a ray skip them, nodes.
const BLOCK_NODES: usize = 16;

/// How much each terrain node is in shadow, 0 (lit) to 1, row by row.
pub(super) fn node_shadows(world: &World, sun: &Vector3<f64>) -> Vec<f32> {
    let side = WORLD_SIZE * NODES_PER_M;
    let horizontal = sun.x.hypot(sun.y);
    if sun.z <= 0.0 || horizontal < 1e-9 {
        return vec![if sun.z <= 0.0 { 1.0 } else { 0.0 }; side * side];
    }
    let solids = Solids::of(world);
    let (dx, dy, rise) = (sun.x / horizontal * STEP_M, sun.y / horizontal * STEP_M, sun.z / horizontal * STEP_M);
    (0..side * side)
        .map(|i| {
            let (x, y) = (((i % side) as f64 + 0.5) * TERRAIN_STEP_M, ((i / side) as f64 + 0.5) * TERRAIN_STEP_M);
            let start = world.terrain().height_at(x, y) as f64;
            let mut shadow = 0.0f64;
            for k in 1.. {
                let (px, py, pz) = (x + dx * k as f64, y + dy * k as f64, start + rise * k as f64);
                if pz > solids.highest_m || shadow >= 1.0 {
                    break;
                }
                if pz > solids.block_highest_m(px, py) {
                    continue;
                }
                let above = solids.highest_at(world, px, py, pz) - pz;
                shadow = shadow.max(((above + PENUMBRA_M / 2.0) / PENUMBRA_M).clamp(0.0, 1.0));
            }
            shadow as f32
        })
        .collect()
}

/// What can cast a shadow: the terrain and the surveyed rocks, each rock's column over every node
/// it covers, and the highest solid of each block of nodes.
struct Solids {
    /// The lowest bottom and highest top of rock over each node (none: `f32::MAX`, `f32::MIN`).
    rock_m: Vec<(f32, f32)>,
    block_highest: Vec<f32>,
    highest_m: f64,
}

impl Solids {
    fn of(world: &World) -> Self {
        let side = WORLD_SIZE * NODES_PER_M;
        let mut rock_m = vec![(f32::MAX, f32::MIN); side * side];
        for rock in world.surveyed_rocks() {
            for (i, column) in rock.columns.iter().enumerate() {
                let Some(column) = column else { continue };
                let x = rock.origin_m[0] + ((i % rock.cols) as f64 + 0.5) * rock.cell_m;
                let y = rock.origin_m[1] + ((i / rock.cols) as f64 + 0.5) * rock.cell_m;
                if let Some(node) = node_at(x, y) {
                    let (bottom, top) = &mut rock_m[node];
                    (*bottom, *top) = (bottom.min(column.bottom_m), top.max(column.top_m));
                }
            }
        }
        let blocks = side / BLOCK_NODES;
        let mut block_highest = vec![0.0f32; blocks * blocks];
        for (i, (x, y, h)) in world.terrain().nodes().enumerate() {
            let block =
                (y / TERRAIN_STEP_M) as usize / BLOCK_NODES * blocks + (x / TERRAIN_STEP_M) as usize / BLOCK_NODES;
            block_highest[block] = block_highest[block].max(h).max(rock_m[i].1);
        }
        let highest_m = block_highest.iter().copied().fold(0.0, f32::max) as f64;
        Solids { rock_m, block_highest, highest_m }
    }

    /// The highest solid anywhere in the block of nodes around (x, y), metres; outside the
    /// world, the highest of all.
    fn block_highest_m(&self, x_m: f64, y_m: f64) -> f64 {
        let blocks = WORLD_SIZE * NODES_PER_M / BLOCK_NODES;
        match node_at(x_m, y_m) {
            Some(node) => {
                let side = WORLD_SIZE * NODES_PER_M;
                let (nx, ny) = (node % side, node / side);
                self.block_highest[ny / BLOCK_NODES * blocks + nx / BLOCK_NODES] as f64
            }
            None => self.highest_m,
        }
    }

    /// The highest solid at (x, y) that reaches up to height `z` or above it: the terrain, or
    /// rock whose column spans `z`.
    fn highest_at(&self, world: &World, x_m: f64, y_m: f64, z_m: f64) -> f64 {
        let ground = world.terrain().height_at(x_m, y_m) as f64;
        let rock = node_at(x_m, y_m)
            .map(|node| self.rock_m[node])
            .filter(|&(bottom, _)| bottom as f64 <= z_m)
            .map_or(f64::MIN, |(_, top)| top as f64);
        ground.max(rock)
    }
}

/// The node under (x, y), if it lies in the world.
fn node_at(x_m: f64, y_m: f64) -> Option<usize> {
    let side = WORLD_SIZE * NODES_PER_M;
    let (nx, ny) = (x_m / TERRAIN_STEP_M, y_m / TERRAIN_STEP_M);
    ((0.0..side as f64).contains(&nx) && (0.0..side as f64).contains(&ny)).then(|| ny as usize * side + nx as usize)
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
