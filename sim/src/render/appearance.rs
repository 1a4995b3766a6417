//! How the world looks, baked once per world: the terrain's shading and colours node by node,
//! the detail textures, and the colours of the floor and the fog by depth.

use std::ops::{Add, Mul, Sub};

use nalgebra::Vector3;
use wide::bytemuck::cast;
use wide::{f32x4, i16x8, i32x4, i32x8, u8x16};

use super::truncated_index;
use crate::look::Look;
use crate::random::value_noise;
use crate::terrain::{NODES_PER_M, Terrain, signed_edge_distances_m};
use crate::world::{WORLD_SIZE, World};

/// Entries of the table of floor colours by depth and their spacing, per metre (the colour is
/// the far one beyond the table).
const FLOOR_TABLE_LEN: usize = 1024;
const FLOOR_TABLE_PER_M: f64 = 50.0;
/// Exponential-squared fog density of the Unity scene.
const FOG_DENSITY: f64 = 0.005;
/// Fog colour of the Unity scene.
const FOG_RGB: [f32; 3] = [139.0, 125.0, 114.0];
/// Side of the tileable detail textures, texels.
const TEXTURE_SIDE: usize = 256;
/// Texel size of the floor detail texture, metres.
const FLOOR_TEXEL_M: f64 = 0.04;
/// Texel size of the rock detail texture, metres.
const ROCK_TEXEL_M: f64 = 0.12;
/// Fixed-point shift of the brightness factors (1.0 = 256).
const FIXED_BITS: u32 = 8;

/// How a terrain node is lit and coloured, baked once per world: the weight of rock against
/// floor, the floor's brightness (its patches and the shadows cast on it), the rock's sunlight,
/// how far the node lies from the foot of the walls (the floor darkens there, by how much depends
/// on how far off it is seen: [`Appearance::near_wall`]) and which way the ground faces (for its
/// texture).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct NodeShade {
    pub(super) rock: f32,
    pub(super) floor: f32,
    pub(super) sun: f32,
    pub(super) wall_m: f32,
    pub(super) facing: Facing,
}

/// Which way a surface faces, to lay its rock texture on it: flat ground takes the texture from
/// above, steep faces from the side they face.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) enum Facing {
    /// Flatter than 45 degrees.
    #[default]
    Up,
    /// Steep, facing east or west.
    AlongX,
    /// Steep, facing north or south.
    AlongY,
}

impl Facing {
    /// The way a surface with this normal faces.
    pub(super) fn of_normal(normal: &Vector3<f64>) -> Self {
        let across = normal.abs();
        if across.z >= across.x.max(across.y) {
            Facing::Up
        } else if across.x >= across.y {
            Facing::AlongX
        } else {
            Facing::AlongY
        }
    }

    /// Texture coordinates of the point (x, y, z) on a surface facing this way, metres.
    pub(super) fn texture_coordinates(self, x: f32, y: f32, z: f32) -> (f32, f32) {
        match self {
            Facing::Up => (x, y),
            Facing::AlongX => (y, z),
            Facing::AlongY => (x, z),
        }
    }
}

/// A [`NodeShade`] in five bytes (rock and sun in 1/255, floor in 1/200, the distance from the
/// walls in 1/32 m up to [`WALL_PACKED_MAX_M`]), so that the shading of the whole terrain stays
/// small enough for the caches.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct PackedShade {
    lanes: [u8; 4],
    facing: u8,
}

/// Scales of the packed lanes: rock, floor (it can exceed 1 a little), sun, distance from the
/// walls.
const LANE_SCALES: [f32; 4] = [255.0, 200.0, 255.0, 32.0];
/// Farther from the walls than this, the floor is as far as the packing tells, metres.
const WALL_PACKED_MAX_M: f32 = 255.0 / 32.0;

impl PackedShade {
    fn pack(shade: &NodeShade) -> Self {
        let values = [shade.rock, shade.floor, shade.sun, shade.wall_m];
        let lanes = std::array::from_fn(|k| (values[k] * LANE_SCALES[k]).round().clamp(0.0, 255.0) as u8);
        PackedShade { lanes, facing: shade.facing as u8 }
    }

    /// Rock, floor, sun and distance from the walls as floats, in their packed units.
    fn lanes(self) -> f32x4 {
        f32x4::new(self.lanes.map(f32::from))
    }

    /// The shade whose values are `lanes` in the packed units, facing as this one.
    fn with_lanes(self, lanes: f32x4) -> NodeShade {
        let [rock, floor, sun, wall_m] = (lanes / f32x4::new(LANE_SCALES)).to_array();
        let facing = [Facing::Up, Facing::AlongX, Facing::AlongY][self.facing as usize % 3];
        NodeShade { rock, floor, sun, wall_m, facing }
    }

    fn rock(self) -> f32 {
        self.lanes[0] as f32 / LANE_SCALES[0]
    }
}

/// Textures and baked shading of one world.
pub(super) struct Appearance {
    pub(super) look: Look,
    floor_detail: Vec<u16>,
    rock_detail: Vec<u16>,
    shades: Vec<PackedShade>,
    side: usize,
    plain_floor: Vec<bool>,
    floor_by_depth: Vec<[f32; 3]>,
}

impl Appearance {
    /// Bakes how `world` looks: the shade of every terrain node, the cells of plain floor and the
    /// floor's colour by depth.
    pub(super) fn new(world: &World) -> Self {
        let look = world.look;
        let terrain = world.terrain();
        let side = WORLD_SIZE * NODES_PER_M;
        let paint_m = signed_edge_distances_m(world.painted());
        let shadows = super::shadows::node_shadows(world, &look.sun);
        let shades: Vec<PackedShade> = terrain
            .nodes()
            .zip(paint_m)
            .zip(shadows)
            .map(|(((x, y, h), paint_m), shadow)| node_shade(terrain, &look, [x, y, h as f64], paint_m as f32, shadow))
            .map(|shade| PackedShade::pack(&shade))
            .collect();
        let plain_floor = (0..WORLD_SIZE * WORLD_SIZE)
            .map(|cell| {
                let (cx, cy) = (cell % WORLD_SIZE, cell / WORLD_SIZE);
                let nodes = |c: usize| (c * NODES_PER_M).saturating_sub(1)..((c + 1) * NODES_PER_M + 1).min(side);
                terrain.cell_max_height(cx as i64, cy as i64) <= 0.0
                    && nodes(cy).all(|ny| nodes(cx).all(|nx| shades[ny * side + nx].rock() == 0.0))
            })
            .collect();
        Appearance {
            look,
            floor_detail: floor_texture(
                look.floor_texture,
                look.floor_dimples,
                look.floor_dimple_depth,
                21 ^ look.texture_salt,
            ),
            rock_detail: tileable_texture(look.rock_texture, 22 ^ look.texture_salt, 4.0),
            shades,
            side,
            plain_floor,
            floor_by_depth: (0..FLOOR_TABLE_LEN)
                .map(|i| {
                    let depth = (i as f64 + 0.5) / FLOOR_TABLE_PER_M;
                    let near_far = 1.0 - (-depth / look.floor_far_m as f64).exp() as f32;
                    lerp3(look.floor_near_rgb, look.floor_far_rgb, near_far)
                })
                .collect(),
        }
    }

    /// True if cell (column `ix`, row `iy`) is flat floor with the floor's colour all over.
    pub(super) fn is_plain_floor(&self, ix: i64, iy: i64) -> bool {
        let size = WORLD_SIZE as i64;
        (0..size).contains(&ix) && (0..size).contains(&iy) && self.plain_floor[iy as usize * WORLD_SIZE + ix as usize]
    }

    /// The baked shade at (x, y), bilinear between the nodes around it (which way it faces: the
    /// nearest node's).
    pub(super) fn shade_at(&self, x: f64, y: f64) -> NodeShade {
        let (corners, [fx, fy]) = self.corners_around(x, y);
        let nearest = corners[(fx >= 0.5) as usize + 2 * (fy >= 0.5) as usize];
        nearest.with_lanes(bilinear(corners.map(PackedShade::lanes), fx, fy))
    }

    /// The four nodes around (x, y) (lower-left, lower-right, upper-left, upper-right) and where
    /// (x, y) lies between them.
    fn corners_around(&self, x: f64, y: f64) -> ([PackedShade; 4], [f32; 2]) {
        let per_m = NODES_PER_M as f64;
        let (gx, gy) = ((x * per_m - 0.5).max(0.0), (y * per_m - 0.5).max(0.0));
        let last = self.side - 1;
        let (ix, iy) = (truncated_index(gx).min(last - 1), truncated_index(gy).min(last - 1));
        let fractions = [((gx - ix as f64) as f32).min(1.0), ((gy - iy as f64) as f32).min(1.0)];
        let at = |dx: usize, dy: usize| self.shades[(iy + dy) * self.side + ix + dx];
        ([at(0, 0), at(1, 0), at(0, 1), at(1, 1)], fractions)
    }

    /// The floor's brightness at (x, y), seen where one pixel row covers `footprint_m` of ground,
    /// fixed point, with its detail texture.
    pub(super) fn floor_factor(&self, x: f64, y: f64, footprint_m: f32) -> u32 {
        let floor = self.floor_brightness(&self.shade_at(x, y), footprint_m);
        ((floor * (1 << FIXED_BITS) as f32) as u32 * self.floor_texel(x as f32, y as f32)) >> FIXED_BITS
    }

    /// The floor's brightness with shade `shade`, seen where one pixel row covers `footprint_m`
    /// of ground: its own, darkened near the walls ([`Appearance::near_wall`]).
    fn floor_brightness(&self, shade: &NodeShade, footprint_m: f32) -> f32 {
        shade.floor * self.near_wall(shade.wall_m, footprint_m)
    }

    /// How bright the floor is `wall_m` from the foot of the walls (0..1), seen where one pixel
    /// row covers `footprint_m` of ground: the darkening there widens with the footprint, as the
    /// terrain's textures are blurred over what a pixel covers.
    fn near_wall(&self, wall_m: f32, footprint_m: f32) -> f32 {
        if wall_m >= WALL_PACKED_MAX_M {
            return 1.0;
        }
        let look = &self.look;
        let width_m = look.wall_shadow_m + look.wall_shadow_spread * footprint_m;
        1.0 - look.wall_shadow * exp_minus(wall_m / width_m)
    }

    /// A pixel of flat ground at (x, y) whose colour may have turned to rock, given the floor's
    /// colour there (`floor_rgb`, fog included), the fog's weights and the ground one pixel row
    /// covers there; and its rock weight.
    pub(super) fn painted_floor(
        &self,
        x: f64,
        y: f64,
        floor_rgb: [f32; 3],
        fog: (f32, [f32; 3]),
        footprint_m: f32,
    ) -> ([u8; 3], f32) {
        let (visible, haze) = fog;
        let node = self.shade_at(x, y);
        let NodeShade { rock, sun, .. } = node;
        let floor_rgb = scale3(floor_rgb, self.floor_brightness(&node, footprint_m));
        let rock_rgb = scale3(self.rock_rgb(sun), visible);
        let (x, y) = (x as f32, y as f32);
        let floor_texture = self.floor_texel(x, y) as f32;
        let texture = floor_texture + (self.rock_texel(x, y) as f32 - floor_texture) * rock;
        (shade(lerp3(floor_rgb, rock_rgb, rock), texture as u32, haze), rock)
    }

    /// The floor's detail texture at (x, y), fixed point.
    pub(super) fn floor_texel(&self, x: f32, y: f32) -> u32 {
        let (u, v) = self.floor_texture_coordinates(x, y);
        texel(&self.floor_detail, u, v)
    }

    /// The rock texture at texture coordinates (a, b) metres (see [`Facing::texture_coordinates`]),
    /// fixed point.
    pub(super) fn rock_texel(&self, a: f32, b: f32) -> u32 {
        let (u, v) = self.rock_texture_coordinates(a, b);
        texel(&self.rock_detail, u, v)
    }

    /// The floor texture's texel coordinates of (x, y).
    pub(super) fn floor_texture_coordinates(&self, x: f32, y: f32) -> (f32, f32) {
        let scale = (1.0 / FLOOR_TEXEL_M) as f32;
        (x * scale, y * scale)
    }

    /// The rock texture's texel coordinates of texture coordinates (a, b) metres.
    pub(super) fn rock_texture_coordinates(&self, a: f32, b: f32) -> (f32, f32) {
        let scale = (1.0 / ROCK_TEXEL_M) as f32;
        (a * scale, b * scale)
    }

    /// The floor's detail texture at texel coordinates (u, v) in 1/256 texel, fixed point.
    pub(super) fn floor_texel_fixed(&self, u: i32, v: i32) -> u32 {
        texel_fixed(&self.floor_detail, u, v)
    }

    /// The rock texture at texel coordinates (u, v) in 1/256 texel, fixed point.
    pub(super) fn rock_texel_fixed(&self, u: i32, v: i32) -> u32 {
        texel_fixed(&self.rock_detail, u, v)
    }

    /// Colour of the floor `depth` metres ahead, before its brightness factor.
    pub(super) fn floor_rgb(&self, depth: f64) -> [f32; 3] {
        let index = truncated_index(depth * FLOOR_TABLE_PER_M).min(self.floor_by_depth.len() - 1);
        self.floor_by_depth[index]
    }

    /// Colour of a terrain point with shade `shade` seen at `depth`, where one pixel row covers
    /// `footprint_m` of ground, before texture and fog.
    pub(super) fn terrain_rgb(&self, shade: &NodeShade, depth: f64, footprint_m: f32) -> [f32; 3] {
        let floor = scale3(self.floor_rgb(depth), self.floor_brightness(shade, footprint_m));
        lerp3(floor, self.rock_rgb(shade.sun), shade.rock)
    }

    /// How squarely a surface facing `normal` faces the sun, 0..1.
    pub(super) fn sunlight(&self, normal: &Vector3<f64>) -> f32 {
        normal.dot(&self.look.sun).max(0.0) as f32
    }

    /// Colour of rock lit by `sun` (0..1), before texture and fog.
    pub(super) fn rock_rgb(&self, sun: f32) -> [f32; 3] {
        self.sunlit(self.look.rock_shade_rgb, self.look.rock_lit_rgb, sun)
    }

    /// Colour of a boulder lit by `sun` (0..1), before texture and fog.
    pub(super) fn boulder_rgb(&self, sun: f32) -> [f32; 3] {
        self.sunlit(self.look.boulder_shade_rgb, self.look.boulder_lit_rgb, sun)
    }

    /// A rock surface's colour between `shade_rgb` and `lit_rgb`, lit by `sun` (0..1): fully
    /// lit from [`Look::rock_full_sun`] on.
    fn sunlit(&self, shade_rgb: [f32; 3], lit_rgb: [f32; 3], sun: f32) -> [f32; 3] {
        lerp3(shade_rgb, lit_rgb, (sun / self.look.rock_full_sun).min(1.0))
    }
}

/// The value at fractions (fx, fy) between four corner values (lower-left, lower-right,
/// upper-left, upper-right): numbers, or vectors of them lane by lane.
fn bilinear<T>([a, b, c, d]: [T; 4], fx: f32, fy: f32) -> T
where
    T: Copy + Add<Output = T> + Sub<Output = T> + Mul<f32, Output = T>,
{
    let top = a + (b - a) * fx;
    top + (c + (d - c) * fx - top) * fy
}

/// The baked shade of the terrain node at `node` (x, y, height), `paint_m` beyond the painted
/// floor, `shadow` (0..1) in the shadow of what stands between it and the sun.
fn node_shade(terrain: &Terrain, look: &Look, node: [f64; 3], paint_m: f32, shadow: f32) -> NodeShade {
    let [x, y, h] = node;
    let h = h as f32;
    let [gx, gy] = terrain.gradient_at(x, y);
    let length = (gx * gx + gy * gy + 1.0).sqrt();
    let normal = Vector3::new(-gx, -gy, 1.0) / length;
    let sun = normal.dot(&look.sun).max(0.0) * (1.0 - look.shadow_rock * shadow) as f64;
    let by_height = smoothstep((h - look.rock_from_height_m) / look.rock_blend_m + 0.5);
    let by_paint = smoothstep((paint_m - look.paint_edge_m) / look.paint_blend_m + 0.5);
    let rock = by_height.max(by_paint);
    let wall_m = (-terrain.edge_distance_at(x, y)).max(0.0);
    let patches = 1.0 + 0.07 * (value_noise(x, y, 3.0, 11 ^ look.texture_salt) as f64 - 0.5) * 2.0;
    let shaded = 1.0 - (look.shadow_floor * shadow) as f64;
    NodeShade { rock, floor: (patches * shaded) as f32, sun: sun as f32, wall_m, facing: Facing::of_normal(&normal) }
}

/// e^-x for x >= 0, from a table (beyond its end, 0).
fn exp_minus(x: f32) -> f32 {
    let index = (x * EXP_TABLE_PER_UNIT) as usize;
    EXP_MINUS.get(index).copied().unwrap_or(0.0)
}

/// Entries of the table of e^-x per unit of x, and their number.
const EXP_TABLE_PER_UNIT: f32 = 64.0;
const EXP_TABLE_LEN: usize = 1024;

static EXP_MINUS: std::sync::LazyLock<[f32; EXP_TABLE_LEN]> =
    std::sync::LazyLock::new(|| std::array::from_fn(|i| (-(i as f64 + 0.5) / EXP_TABLE_PER_UNIT as f64).exp() as f32));

fn smoothstep(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn to_fixed(factor: f64) -> u16 {
    (factor * (1 << FIXED_BITS) as f64).round().clamp(0.0, u16::MAX as f64) as u16
}

/// `rgb` times a fixed-point factor, plus `offset`, rounded and saturated to a pixel.
#[inline]
pub(super) fn shade(rgb: [f32; 3], factor: u32, offset: [f32; 3]) -> [u8; 3] {
    let f = factor as f32 * (1.0 / (1 << FIXED_BITS) as f32);
    let lanes = |c: [f32; 3]| f32x4::new([c[0], c[1], c[2], 0.0]);
    saturated_pixel((lanes(rgb) * f32x4::splat(f) + lanes(offset) + f32x4::splat(0.5)).fast_trunc_int())
}

/// The same in fixed point: `rgb` and `offset` in 1/256 in the first three lanes, none negative,
/// the factor with [`FIXED_BITS`].
#[inline]
pub(super) fn shade_fixed(rgb: i32x4, factor: u32, offset: i32x4) -> [u8; 3] {
    let scaled: i32x4 = (rgb * i32x4::splat(factor as i32)) >> (8 + FIXED_BITS);
    saturated_pixel(scaled + (offset >> 8_u32))
}

/// The first three lanes as a pixel, each saturated to 0..=255 by the processor's packs.
#[inline]
fn saturated_pixel(lanes: i32x4) -> [u8; 3] {
    let padded: i32x8 = cast([lanes, i32x4::ZERO]);
    let [r, g, b, ..] = u8x16::narrow_i16x8(i16x8::from_i32x8_saturate(padded), i16x8::ZERO).to_array();
    [r, g, b]
}

pub(super) fn to_rgb8(rgb: [f32; 3]) -> [u8; 3] {
    rgb.map(|c| (c + 0.5).clamp(0.0, 255.0) as u8)
}

/// A tileable texture of fixed-point factors around 1 with amplitude `amplitude`, made of value noise.
fn tileable_texture(amplitude: f32, salt: u64, features: f64) -> Vec<u16> {
    tileable_noise(salt, features, 0.6).iter().map(|n| to_fixed((1.0 + amplitude * (n - 0.5) * 2.0) as f64)).collect()
}

/// The floor's texture: value noise of amplitude `amplitude`, with dark dimples over `dimples` of
/// its area, up to `dimple_depth` darker (the shadows of Unity's bump-mapped floor).
fn floor_texture(amplitude: f32, dimples: f32, dimple_depth: f32, salt: u64) -> Vec<u16> {
    let base = tileable_noise(salt, 6.0, 0.6);
    let pits = tileable_noise(salt.wrapping_add(7), 14.0, 0.8);
    let mut sorted = pits.clone();
    sorted.sort_by(f32::total_cmp);
    let threshold = sorted[((1.0 - dimples.clamp(0.0, 1.0)) * (sorted.len() - 1) as f32) as usize];
    base.iter()
        .zip(&pits)
        .map(|(n, p)| {
            let dimple = dimple_depth * smoothstep((p - threshold) / 0.04 + 0.5);
            to_fixed(((1.0 + amplitude * (n - 0.5) * 2.0) * (1.0 - dimple)) as f64)
        })
        .collect()
}

/// Tileable value noise in 0..1 over `TEXTURE_SIDE` x `TEXTURE_SIDE` texels, with about
/// `features` features across, two octaves (the first weighted `first`).
fn tileable_noise(salt: u64, features: f64, first: f32) -> Vec<f32> {
    let side = TEXTURE_SIDE as f64;
    (0..TEXTURE_SIDE * TEXTURE_SIDE)
        .map(|i| {
            let (u, v) = ((i % TEXTURE_SIDE) as f64 / side, (i / TEXTURE_SIDE) as f64 / side);
            let periodic = |scale: f64, s: u64| {
                let (a, b) = ((u * std::f64::consts::TAU).cos(), (u * std::f64::consts::TAU).sin());
                let (c, d) = ((v * std::f64::consts::TAU).cos(), (v * std::f64::consts::TAU).sin());
                value_noise(a * scale + c * scale * 0.37, b * scale + d * scale, 1.0, s)
            };
            first * periodic(features, salt) + (1.0 - first) * periodic(features * 3.1, salt.wrapping_add(1))
        })
        .collect()
}

/// The texel at coordinates (u, v) in 1/256 texel, wrapping around.
fn texel_fixed(texture: &[u16], u: i32, v: i32) -> u32 {
    let mask = TEXTURE_SIDE as i32 - 1;
    texture[(((v >> 8) & mask) * TEXTURE_SIDE as i32 + ((u >> 8) & mask)) as usize] as u32
}

/// The texel at coordinates (u, v), wrapping around.
fn texel(texture: &[u16], u: f32, v: f32) -> u32 {
    let mask = TEXTURE_SIDE as i32 - 1;
    let (x, y) = ((u as i32) & mask, (v as i32) & mask);
    texture[(y * TEXTURE_SIDE as i32 + x) as usize] as u32
}

/// Fog at `distance`: the weight of the surface colour and the fog colour already weighted.
pub(super) fn fog_weights(distance: f64) -> (f32, [f32; 3]) {
    let visible = FOG_VISIBLE[truncated_index(distance * FOG_TABLE_PER_M).min(FOG_TABLE_LEN - 1)];
    (visible, scale3(FOG_RGB, 1.0 - visible))
}

/// Entries of the fog table and their spacing, per metre of depth.
const FOG_TABLE_LEN: usize = 1200;
const FOG_TABLE_PER_M: f64 = 4.0;

/// How much of a surface shows through the fog at each depth of the table.
static FOG_VISIBLE: std::sync::LazyLock<[f32; FOG_TABLE_LEN]> = std::sync::LazyLock::new(|| {
    std::array::from_fn(|i| (-(FOG_DENSITY * (i as f64 + 0.5) / FOG_TABLE_PER_M).powi(2)).exp() as f32)
});

pub(super) fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t]
}

pub(super) fn scale3(rgb: [f32; 3], factor: f32) -> [f32; 3] {
    [rgb[0] * factor, rgb[1] * factor, rgb[2] * factor]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_saturates_each_channel_as_a_float_to_byte_conversion_does() {
        for value in [-70_000, -1, 0, 1, 128, 254, 255, 256, 40_000, 70_000] {
            let [r, g, b] = saturated_pixel(i32x4::new([value, value / 2, -value, 9]));
            assert_eq!([r, g, b], [value, value / 2, -value].map(|v| v as f32 as u8), "{value}");
        }
    }

    #[test]
    fn float_and_fixed_point_shading_agree_within_a_level() {
        let (rgb, haze) = ([180.5, 97.25, 300.0], [12.75, 0.0, 3.5]);
        let fixed = |c: [f32; 3]| i32x4::new([c[0], c[1], c[2], 0.0].map(|v| (v * 256.0) as i32));
        for factor in [0, 100, 256, 300, 511] {
            let float = shade(rgb, factor, haze);
            let exact = shade_fixed(fixed(rgb), factor, fixed(haze));
            for (f, x) in float.iter().zip(exact) {
                assert!(f.abs_diff(x) <= 1, "factor {factor}: {float:?} against {exact:?}");
            }
        }
        assert_eq!(shade(rgb, 300, haze)[2], 255, "a channel above 255 saturates");
    }
}
