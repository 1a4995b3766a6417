//! How a world looks to the camera: the sun, the colours of floor, rock and sky, and the texture
//! pattern. Appearance seed 0 is the look calibrated against the real Unity frames; other seeds
//! vary it within what the real frames show, so that nothing is tuned to one rendering.

use nalgebra::Vector3;

use crate::random::SplitMix64;

/// The look of a world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Look {
    /// Unit vector towards the sun (east, north, up).
    pub sun: Vector3<f64>,
    /// Floor colour right in front of the camera.
    pub floor_near_rgb: [f32; 3],
    /// Floor colour a few metres away.
    pub floor_far_rgb: [f32; 3],
    /// The floor's colour changes from near to far over about this distance, metres.
    pub floor_far_m: f32,
    /// Relative brightness variation of the floor's texture.
    pub floor_texture: f32,
    /// Fraction of the floor covered by dark dimples.
    pub floor_dimples: f32,
    /// How much darker the floor is at the bottom of a dimple (0..1).
    pub floor_dimple_depth: f32,
    /// Rock colour in full sun, before texture.
    pub rock_lit_rgb: [f32; 3],
    /// Rock colour in shade.
    pub rock_shade_rgb: [f32; 3],
    /// Colour of the rock obstacles (boulders) in full sun, before texture: darker than the walls.
    pub boulder_lit_rgb: [f32; 3],
    /// Colour of the rock obstacles in shade.
    pub boulder_shade_rgb: [f32; 3],
    /// Rock is fully lit once it faces the sun this squarely (cosine of the angle, 0..1).
    pub rock_full_sun: f32,
    /// Relative brightness variation of the rock's texture.
    pub rock_texture: f32,
    /// How much darker the floor is right at the foot of a wall (0..1).
    pub wall_shadow: f32,
    /// Over about this distance from the wall, metres...
    pub wall_shadow_m: f32,
    /// ...widened, seen from afar, by this share of the ground one pixel row covers (the
    /// terrain's textures are blurred over what a pixel covers).
    pub wall_shadow_spread: f32,
    /// How much darker the floor is in the shadow cast by walls and rocks (0..1).
    pub shadow_floor: f32,
    /// How much of the sunlight a rock face in a cast shadow loses (0..1).
    pub shadow_rock: f32,
    /// Sky at the top of the image.
    pub sky_top_rgb: [f32; 3],
    /// Sky at the horizon.
    pub sky_horizon_rgb: [f32; 3],
    /// Terrain height where the floor colour gives way to rock, metres (half-way point).
    pub rock_from_height_m: f32,
    /// Height over which that change happens, metres.
    pub rock_blend_m: f32,
    /// The floor's texture is painted on the navigable map; this far beyond its edge it has given
    /// way half to rock, metres.
    pub paint_edge_m: f32,
    /// Distance over which the paint fades, metres.
    pub paint_blend_m: f32,
    /// Salt of the texture pattern.
    pub texture_salt: u64,
}

impl Default for Look {
    fn default() -> Self {
        Look {
            sun: Vector3::new(0.321, -0.557, 0.766),
            floor_near_rgb: [246.0, 233.0, 218.0],
            floor_far_rgb: [222.0, 202.0, 188.0],
            floor_far_m: 2.5,
            floor_texture: 0.06,
            floor_dimples: 0.0,
            floor_dimple_depth: 0.0,
            rock_lit_rgb: [46.0, 32.0, 27.0],
            rock_shade_rgb: [10.0, 7.0, 5.0],
            boulder_lit_rgb: [22.0, 14.0, 11.0],
            boulder_shade_rgb: [6.0, 3.0, 2.0],
            rock_full_sun: 0.5,
            rock_texture: 0.45,
            wall_shadow: 0.65,
            wall_shadow_m: 0.3,
            wall_shadow_spread: 0.15,
            shadow_floor: 0.1,
            shadow_rock: 0.5,
            sky_top_rgb: [112.0, 104.0, 99.0],
            sky_horizon_rgb: [127.0, 118.0, 112.0],
            rock_from_height_m: 0.02,
            rock_blend_m: 0.04,
            paint_edge_m: 0.0,
            paint_blend_m: 1.0,
            texture_salt: 0,
        }
    }
}

/// Largest change of the sun's azimuth between looks, degrees.
const SUN_AZIMUTH_JITTER_DEG: f64 = 40.0;
/// Largest change of the sun's elevation, degrees.
const SUN_ELEVATION_JITTER_DEG: f64 = 12.0;
/// Largest relative change of a surface's brightness.
const BRIGHTNESS_JITTER: f64 = 0.06;
/// Largest relative change of one colour channel against the others.
const TINT_JITTER: f64 = 0.025;
/// Largest share of the floor under dark dimples, and their largest depth: the real floor fails
/// the navigable colour rule on 3-7 % of its pixels within 6 m (by its bump-mapped dimples);
/// the calibrated look leaves them out, as they cannot coincide with the real ones pixel by pixel.
const DIMPLES_MAX: f64 = 0.05;
const DIMPLE_DEPTH_MAX: f64 = 0.3;

impl Look {
    /// The look of appearance seed `seed`: 0 is the calibrated look, others vary the sun, the
    /// brightness and tint of each surface, the rock blend and the texture pattern.
    pub fn from_seed(seed: u64) -> Self {
        let base = Look::default();
        if seed == 0 {
            return base;
        }
        let mut rng = SplitMix64::new(seed ^ 0x1007_c0de);
        let azimuth = base.sun.y.atan2(base.sun.x) + rng.range(-1.0, 1.0) * SUN_AZIMUTH_JITTER_DEG.to_radians();
        let elevation = base.sun.z.asin() + rng.range(-1.0, 1.0) * SUN_ELEVATION_JITTER_DEG.to_radians();
        let mut vary = |rgb: [f32; 3]| {
            let brightness = 1.0 + rng.range(-1.0, 1.0) * BRIGHTNESS_JITTER;
            rgb.map(|c| (c as f64 * brightness * (1.0 + rng.range(-1.0, 1.0) * TINT_JITTER)).clamp(0.0, 255.0) as f32)
        };
        Look {
            sun: Vector3::new(elevation.cos() * azimuth.cos(), elevation.cos() * azimuth.sin(), elevation.sin()),
            floor_near_rgb: vary(base.floor_near_rgb),
            floor_far_rgb: vary(base.floor_far_rgb),
            rock_lit_rgb: vary(base.rock_lit_rgb),
            rock_shade_rgb: vary(base.rock_shade_rgb),
            boulder_lit_rgb: vary(base.boulder_lit_rgb),
            boulder_shade_rgb: vary(base.boulder_shade_rgb),
            sky_top_rgb: vary(base.sky_top_rgb),
            sky_horizon_rgb: vary(base.sky_horizon_rgb),
            rock_from_height_m: base.rock_from_height_m * rng.range(0.8, 1.25) as f32,
            rock_blend_m: base.rock_blend_m * rng.range(0.8, 1.25) as f32,
            floor_dimples: rng.range(0.0, DIMPLES_MAX) as f32,
            floor_dimple_depth: rng.range(0.5, 1.0) as f32 * DIMPLE_DEPTH_MAX as f32,
            texture_salt: seed,
            ..base
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed_zero_is_the_calibrated_look_and_others_stay_near_it() {
        assert_eq!(Look::from_seed(0), Look::default());
        let base = Look::default();
        for seed in 1..50 {
            let look = Look::from_seed(seed);
            assert_ne!(look, base);
            assert!((look.sun.norm_squared() - 1.0).abs() < 1e-9, "the sun is a unit vector");
            assert!(look.sun.z > 0.5, "the sun stays high: {:?}", look.sun);
            for (a, b) in look.floor_near_rgb.iter().zip(base.floor_near_rgb) {
                assert!((a - b).abs() <= b * 0.09 + 1.0, "seed {seed}: floor {a} against {b}");
            }
        }
        assert_eq!(Look::from_seed(7), Look::from_seed(7));
    }
}
