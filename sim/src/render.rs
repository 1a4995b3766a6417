//! The camera renderer: walls of the height field, floor, sky and the yellow samples, with colours,
//! texture, shading and fog like the Unity frames (unity-sim-spec 4.3), from the rover's camera.
//!
//! Each frame is first drawn for a level camera (yaw only) at the true camera position, column
//! by column like a voxel-space renderer: every image column is a vertical plane, marched through
//! the grid front to back. Body pitch and roll are a pure rotation about the camera centre, applied
//! afterwards as an exact image-space resampling of the level view.

use rover_imaging::RgbImage;

use crate::camera::{BodyPose, CameraModel, tilt};
use crate::random::{hash2, mix64, value_noise};
use crate::world::{MAX_TERRAIN_HEIGHT_M, Sample, WORLD_SIZE, World};

/// Extra pixels around the level view, so that pitch and roll up to a few degrees stay inside it.
const MARGIN_PX: usize = 16;
/// Rays stop after this horizontal depth, metres.
const MAX_DEPTH_M: f64 = 160.0;
/// Exponential-squared fog density of the Unity scene.
const FOG_DENSITY: f64 = 0.005;
/// Fog colour of the Unity scene.
const FOG_RGB: [f32; 3] = [139.0, 125.0, 114.0];
/// Direction towards the sun (east, north, up), from the scene's light rotation (50, -30, 0).
const SUN: [f64; 3] = [0.32, -0.557, 0.766];
/// Floor colour right in front of the rover and a few metres away (measured on the test frames).
const FLOOR_NEAR_RGB: [f32; 3] = [246.0, 233.0, 218.0];
const FLOOR_FAR_RGB: [f32; 3] = [222.0, 202.0, 188.0];
/// Albedo of walls and boulders.
const ROCK_RGB: [f32; 3] = [46.0, 31.0, 26.0];
/// Sky at the top of the image and at the horizon.
const SKY_TOP_RGB: [f32; 3] = [112.0, 104.0, 99.0];
const SKY_HORIZON_RGB: [f32; 3] = [127.0, 118.0, 112.0];
/// Albedo of the samples (Unity material colour 1.0, 0.848, 0.0 on a rock texture).
const SAMPLE_RGB: [f32; 3] = [232.0, 195.0, 20.0];
/// Colour of the calibration grid lines.
const GRID_RGB: [f32; 3] = [38.0, 36.0, 34.0];
/// Half width of a grid line, metres.
const GRID_HALF_WIDTH_M: f64 = 0.012;
/// Size of the sensor-noise table minus one (a power of two minus one).
const NOISE_MASK: usize = (1 << 16) - 1;
/// Side of the tileable detail textures, texels.
const TEXTURE_SIDE: usize = 256;
/// Texel size of the floor detail texture, metres.
const FLOOR_TEXEL_M: f64 = 0.04;
/// Texel size of the wall detail texture, metres.
const WALL_TEXEL_M: f64 = 0.12;
/// Resolution of the floor shading field, metres.
const SHADE_CELL_M: f64 = 0.25;

/// What a pixel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Surface {
    /// Navigable floor.
    Floor,
    /// A wall or a boulder.
    Rock,
    /// The sky.
    Sky,
    /// A rock sample.
    Sample,
}

/// Rendering options.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RenderOptions {
    /// Draw the 1 m calibration grid on the floor (the Unity "Grid" button).
    pub grid: bool,
}

/// Precomputed textures and shading of one world.
struct Appearance {
    floor_detail: Vec<u16>,
    wall_detail: Vec<u16>,
    floor_shade: Vec<u16>,
    shade_side: usize,
}

impl Appearance {
    fn new(world: &World) -> Self {
        let shade_side = (WORLD_SIZE as f64 / SHADE_CELL_M) as usize;
        let mut floor_shade = Vec::with_capacity(shade_side * shade_side);
        for sy in 0..shade_side {
            for sx in 0..shade_side {
                let (x, y) = ((sx as f64 + 0.5) * SHADE_CELL_M, (sy as f64 + 0.5) * SHADE_CELL_M);
                let wall = world.wall_distance(x, y) as f64;
                let near_wall = 1.0 - 0.42 * (-wall / 0.55).exp();
                let patches = 1.0 + 0.07 * (value_noise(x, y, 3.0, 11) as f64 - 0.5) * 2.0;
                floor_shade.push(to_fixed(near_wall * patches));
            }
        }
        Appearance {
            floor_detail: tileable_texture(0.06, 21, 6.0),
            wall_detail: tileable_texture(0.45, 22, 4.0),
            floor_shade,
            shade_side,
        }
    }

    /// Brightness factor of the floor at (x, y), fixed point (256 = 1).
    fn floor_factor(&self, x: f64, y: f64) -> u32 {
        let last = self.shade_side - 1;
        let sx = ((x * (1.0 / SHADE_CELL_M)).max(0.0) as usize).min(last);
        let sy = ((y * (1.0 / SHADE_CELL_M)).max(0.0) as usize).min(last);
        let detail = texel(&self.floor_detail, x * (1.0 / FLOOR_TEXEL_M), y * (1.0 / FLOOR_TEXEL_M));
        (self.floor_shade[sy * self.shade_side + sx] as u32 * detail) >> FIXED_BITS
    }

    /// Brightness factor of rock at a point of a wall, fixed point (256 = 1).
    fn wall_factor(&self, along: f64, z: f64) -> u32 {
        texel(&self.wall_detail, along * (1.0 / WALL_TEXEL_M), z * (1.0 / WALL_TEXEL_M))
    }
}

/// Fixed-point shift of the brightness factors (1.0 = 256).
const FIXED_BITS: u32 = 8;

fn to_fixed(factor: f64) -> u16 {
    (factor * (1 << FIXED_BITS) as f64).round().clamp(0.0, u16::MAX as f64) as u16
}

/// `rgb` (0..255 per channel) times a fixed-point factor, plus `offset`, saturated to a pixel.
fn shade(rgb: [u32; 3], factor: u32, offset: [u32; 3]) -> [u8; 3] {
    [0, 1, 2].map(|k| (((rgb[k] * factor) >> FIXED_BITS) + offset[k]).min(255) as u8)
}

fn to_rgb8(rgb: [f32; 3]) -> [u8; 3] {
    rgb.map(|c| (c + 0.5).clamp(0.0, 255.0) as u8)
}

fn to_rgb32(rgb: [f32; 3]) -> [u32; 3] {
    rgb.map(|c| (c + 0.5).clamp(0.0, 255.0) as u32)
}

/// A tileable texture of fixed-point factors around 1 with amplitude `amplitude`, made of value noise.
fn tileable_texture(amplitude: f32, salt: u64, features: f64) -> Vec<u16> {
    let side = TEXTURE_SIDE as f64;
    let mut texture = Vec::with_capacity(TEXTURE_SIDE * TEXTURE_SIDE);
    for ty in 0..TEXTURE_SIDE {
        for tx in 0..TEXTURE_SIDE {
            let (u, v) = (tx as f64 / side, ty as f64 / side);
            let periodic = |scale: f64, s: u64| {
                let (a, b) = ((u * std::f64::consts::TAU).cos(), (u * std::f64::consts::TAU).sin());
                let (c, d) = ((v * std::f64::consts::TAU).cos(), (v * std::f64::consts::TAU).sin());
                value_noise(a * scale + c * scale * 0.37, b * scale + d * scale, 1.0, s)
            };
            let n = 0.6 * periodic(features, salt) + 0.4 * periodic(features * 3.1, salt + 1);
            texture.push(to_fixed((1.0 + amplitude * (n - 0.5) * 2.0) as f64));
        }
    }
    texture
}

fn texel(texture: &[u16], u: f64, v: f64) -> u32 {
    let mask = TEXTURE_SIDE as i64 - 1;
    let (x, y) = ((u as i64) & mask, (v as i64) & mask);
    texture[(y * TEXTURE_SIDE as i64 + x) as usize] as u32
}

/// Renders camera frames of one world.
pub struct Renderer {
    noise: Vec<i8>,
    window: Window,
    floor_rows: Vec<FloorRow>,
    camera: CameraModel,
    options: RenderOptions,
    appearance: Appearance,
    level_width: usize,
    level_height: usize,
    level: Vec<[u8; 3]>,
    level_surface: Vec<Surface>,
    surfaces: Vec<Surface>,
    depth: Vec<f32>,
    frame: u64,
}

/// The rectangle of the level view drawn for a frame: columns u0..u1, rows v0..v1.
#[derive(Debug, Clone, Copy, Default)]
struct Window {
    u0: usize,
    u1: usize,
    v0: usize,
    v1: usize,
}

/// What every floor pixel of one level row shares: its forward depth and its colour before texture.
#[derive(Debug, Clone, Copy, Default)]
struct FloorRow {
    depth: f64,
    rgb: [u32; 3],
}

/// The level camera of one frame: position and the horizontal axes.
struct LevelView {
    x: f64,
    y: f64,
    height: f64,
    forward: [f64; 2],
    right: [f64; 2],
    cx: f64,
    cy: f64,
    focal: f64,
}

impl LevelView {
    /// Horizontal direction of level column `u`, scaled so that the parameter is forward depth.
    fn column_direction(&self, u: usize) -> [f64; 2] {
        let r = (u as f64 - self.cx) / self.focal;
        [self.forward[0] + r * self.right[0], self.forward[1] + r * self.right[1]]
    }

    /// Row where a point at forward depth `depth` and height `z` appears.
    fn row(&self, depth: f64, z: f64) -> f64 {
        self.cy + self.focal * (self.height - z) / depth
    }
}

impl Renderer {
    /// A renderer for `world`.
    pub fn new(world: &World, camera: CameraModel, options: RenderOptions) -> Self {
        let (level_width, level_height) = (camera.width + 2 * MARGIN_PX, camera.height + 2 * MARGIN_PX);
        Renderer {
            noise: (0..=NOISE_MASK as u64).map(|i| (mix64(i) % 7) as i8 - 3).collect(),
            window: Window::default(),
            floor_rows: vec![FloorRow::default(); level_height],
            camera,
            options,
            appearance: Appearance::new(world),
            level_width,
            level_height,
            level: vec![[0; 3]; level_width * level_height],
            level_surface: vec![Surface::Sky; level_width * level_height],
            surfaces: vec![Surface::Sky; camera.width * camera.height],
            depth: vec![f32::INFINITY; level_width * level_height],
            frame: 0,
        }
    }

    /// What each pixel of the last frame shows, row-major like the image.
    pub fn surfaces(&self) -> &[Surface] {
        &self.surfaces
    }

    /// The camera being rendered.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// Renders the camera view of the rover at `pose`, with `samples` on the ground, into `out`.
    pub fn render(&mut self, world: &World, samples: &[Sample], pose: &BodyPose, out: &mut RgbImage) {
        self.frame = self.frame.wrapping_add(1);
        let [x, y, height] = self.camera.position(pose);
        let (sin_yaw, cos_yaw) = pose.yaw_deg.to_radians().sin_cos();
        let (cx, cy) = self.camera.principal_point();
        let view = LevelView {
            x,
            y,
            height,
            forward: [cos_yaw, sin_yaw],
            right: [sin_yaw, -cos_yaw],
            cx: cx + MARGIN_PX as f64,
            cy: cy + MARGIN_PX as f64,
            focal: self.camera.focal_px,
        };
        let rotation = Rotation::new(pose, &self.camera);
        self.window = self.needed_window(&rotation);
        self.prepare_floor_rows(&view);
        for u in self.window.u0..self.window.u1 {
            self.render_column(world, &view, u);
        }
        for sample in samples {
            self.draw_sample(&view, sample.x_m, sample.y_m, sample.radius_m);
        }
        self.resample(&rotation, out);
    }

    /// The part of the level view the output needs: the camera's own rectangle when level,
    /// otherwise the bounding box of the rotated rectangle plus one pixel for interpolation.
    fn needed_window(&self, rotation: &Rotation) -> Window {
        let (width, height) = (self.camera.width, self.camera.height);
        if rotation.is_identity() {
            return Window { u0: MARGIN_PX, u1: MARGIN_PX + width, v0: MARGIN_PX, v1: MARGIN_PX + height };
        }
        let corners =
            [(0, 0), (width - 1, 0), (0, height - 1), (width - 1, height - 1)].map(|(u, v)| rotation.level_pixel(u, v));
        let (min_u, max_u) = corners.iter().fold((f64::MAX, f64::MIN), |(lo, hi), c| (lo.min(c.0), hi.max(c.0)));
        let (min_v, max_v) = corners.iter().fold((f64::MAX, f64::MIN), |(lo, hi), c| (lo.min(c.1), hi.max(c.1)));
        Window {
            u0: (min_u - 1.0).max(0.0) as usize,
            u1: ((max_u + 2.0).max(0.0) as usize).min(self.level_width),
            v0: (min_v - 1.0).max(0.0) as usize,
            v1: ((max_v + 2.0).max(0.0) as usize).min(self.level_height),
        }
    }

    fn render_column(&mut self, world: &World, view: &LevelView, u: usize) {
        let [dx, dy] = view.column_direction(u);
        let (mut ix, mut iy) = (view.x.floor() as i64, view.y.floor() as i64);
        let (step_x, step_y) = (if dx >= 0.0 { 1 } else { -1 }, if dy >= 0.0 { 1 } else { -1 });
        let next_boundary = |p: f64, i: i64, step: i64| if step > 0 { (i + 1) as f64 - p } else { p - i as f64 };
        let (mut t_x, mut t_y) = (
            if dx == 0.0 { f64::INFINITY } else { next_boundary(view.x, ix, step_x) / dx.abs() },
            if dy == 0.0 { f64::INFINITY } else { next_boundary(view.y, iy, step_y) / dy.abs() },
        );
        let (delta_x, delta_y) = (1.0 / dx.abs(), 1.0 / dy.abs());
        let mut t_in = 0.0;
        let mut normal = [0.0, 0.0];
        let top = self.window.v0;
        let mut bottom = self.window.v1;
        while bottom > top && t_in < MAX_DEPTH_M && view.row(t_in, MAX_TERRAIN_HEIGHT_M as f64) < bottom as f64 {
            let crosses_x = t_x < t_y;
            let t_out = if crosses_x { t_x } else { t_y };
            let height = world.cell_height(ix, iy) as f64;
            bottom = if height <= 0.0 {
                self.draw_floor(view, u, [dx, dy], t_out, bottom)
            } else {
                self.draw_rock(view, u, [dx, dy], (t_in, t_out), height, normal, bottom)
            };
            if crosses_x {
                ix += step_x;
                t_x += delta_x;
                normal = [-step_x as f64, 0.0];
            } else {
                iy += step_y;
                t_y += delta_y;
                normal = [0.0, -step_y as f64];
            }
            t_in = t_out;
        }
        for v in top..bottom {
            let t = v as f32 / view.cy as f32;
            self.put(u, v, to_rgb8(lerp3(SKY_TOP_RGB, SKY_HORIZON_RGB, t.min(1.0))), f32::INFINITY, Surface::Sky);
        }
    }

    fn prepare_floor_rows(&mut self, view: &LevelView) {
        for (v, row) in self.floor_rows.iter_mut().enumerate() {
            if (v as f64) <= view.cy {
                continue;
            }
            let depth = view.focal * view.height / (v as f64 - view.cy);
            let near_far = 1.0 - (-depth / 2.5).exp() as f32;
            *row = FloorRow { depth, rgb: to_rgb32(fog(lerp3(FLOOR_NEAR_RGB, FLOOR_FAR_RGB, near_far), depth)) };
        }
    }

    /// Draws the floor rows of one cell (forward depths up to `t_out`); returns the new bottom.
    fn draw_floor(&mut self, view: &LevelView, u: usize, dir: [f64; 2], t_out: f64, bottom: usize) -> usize {
        let first = (view.row(t_out, 0.0) as usize).saturating_add(1);
        for v in first..bottom {
            let FloorRow { depth, rgb } = self.floor_rows[v];
            let (x, y) = (view.x + depth * dir[0], view.y + depth * dir[1]);
            let mut pixel = shade(rgb, self.appearance.floor_factor(x, y), [0; 3]);
            if self.options.grid {
                let rgb = pixel.map(f32::from);
                pixel = to_rgb8(lerp3(rgb, GRID_RGB, grid_coverage(x, y, depth, view)));
            }
            self.put(u, v, pixel, depth as f32, Surface::Floor);
        }
        first.min(bottom)
    }

    /// Draws the visible part of a rock or wall cell; returns the new bottom.
    #[allow(clippy::too_many_arguments)]
    fn draw_rock(
        &mut self,
        view: &LevelView,
        u: usize,
        dir: [f64; 2],
        (t_in, t_out): (f64, f64),
        height: f64,
        normal: [f64; 2],
        bottom: usize,
    ) -> usize {
        if t_in <= 0.0 && height < view.height {
            return bottom;
        }
        if t_in <= 0.0 {
            for v in self.window.v0..bottom {
                self.put(u, v, to_rgb8(ROCK_RGB), 0.0, Surface::Rock);
            }
            return self.window.v0;
        }
        let face_top = ceil_row(view.row(t_in, height)).max(self.window.v0);
        let lit = 0.55 + 0.9 * (normal[0] * SUN[0] + normal[1] * SUN[1]).max(0.0) as f32;
        let (hx, hy) = (view.x + t_in * dir[0], view.y + t_in * dir[1]);
        let along = if normal[0] != 0.0 { hy } else { hx };
        let (visible, haze) = fog_weights(t_in);
        let (face_rgb, haze) = (to_rgb32(scale3(ROCK_RGB, lit * visible)), to_rgb32(haze));
        for v in face_top..bottom {
            let z = view.height - (v as f64 - view.cy) * t_in / view.focal;
            let pixel = shade(face_rgb, self.appearance.wall_factor(along, z), haze);
            self.put(u, v, pixel, t_in as f32, Surface::Rock);
        }
        let mut top = face_top.min(bottom);
        if height < view.height {
            let surface_top = ceil_row(view.row(t_out, height)).max(self.window.v0);
            let top_rgb = to_rgb32(fog(scale3(ROCK_RGB, 0.55 + 0.9 * SUN[2] as f32), t_in));
            for v in surface_top..top {
                let depth = view.focal * (view.height - height) / (v as f64 - view.cy);
                let (x, y) = (view.x + depth * dir[0], view.y + depth * dir[1]);
                let pixel = shade(top_rgb, self.appearance.wall_factor(x + y, x - y), [0; 3]);
                self.put(u, v, pixel, depth as f32, Surface::Rock);
            }
            top = top.min(surface_top);
        }
        top
    }

    fn draw_sample(&mut self, view: &LevelView, x: f64, y: f64, radius: f64) {
        let centre = [x, y, radius * 0.75];
        let (rx, ry) = (x - view.x, y - view.y);
        let depth = rx * view.forward[0] + ry * view.forward[1];
        if !(0.15..=40.0).contains(&depth) {
            return;
        }
        let lateral = rx * view.right[0] + ry * view.right[1];
        let reach = view.focal * radius * 1.6 / depth + 1.0;
        let u_mid = view.cx + view.focal * lateral / depth;
        let v_mid = view.row(depth, centre[2]);
        let (max_u, max_v) = ((self.level_width - 1) as f64, (self.level_height - 1) as f64);
        let clamp_u = |v: f64| v.clamp(0.0, max_u) as usize;
        let clamp_v = |v: f64| v.clamp(0.0, max_v) as usize;
        for v in clamp_v(v_mid - reach)..=clamp_v(v_mid + reach) {
            for u in clamp_u(u_mid - reach)..=clamp_u(u_mid + reach) {
                let [dx, dy] = view.column_direction(u);
                let dz = -(v as f64 - view.cy) / view.focal;
                let origin = [view.x - centre[0], view.y - centre[1], view.height - centre[2]];
                let a = dx * dx + dy * dy + dz * dz;
                let b = 2.0 * (dx * origin[0] + dy * origin[1] + dz * origin[2]);
                let c = origin.iter().map(|o| o * o).sum::<f64>() - radius * radius;
                let discriminant = b * b - 4.0 * a * c;
                if discriminant < 0.0 {
                    continue;
                }
                let t = (-b - discriminant.sqrt()) / (2.0 * a);
                let index = self.level_index(u, v);
                if t <= 0.0 || t as f32 >= self.depth[index] {
                    continue;
                }
                let normal =
                    [(origin[0] + t * dx) / radius, (origin[1] + t * dy) / radius, (origin[2] + t * dz) / radius];
                let light = normal[0] * SUN[0] + normal[1] * SUN[1] + normal[2] * SUN[2];
                let texture =
                    0.85 + 0.3 * hash2((normal[0] * 9.0) as i64, (normal[1] * 9.0 + normal[2] * 5.0) as i64, 31);
                let brightness = (0.55 + 0.5 * light.max(0.0)) as f32 * texture;
                self.put(u, v, to_rgb8(scale3(SAMPLE_RGB, brightness)), t as f32, Surface::Sample);
            }
        }
    }

    /// The level view is stored column by column, the order in which it is drawn.
    fn level_index(&self, u: usize, v: usize) -> usize {
        u * self.level_height + v
    }

    fn put(&mut self, u: usize, v: usize, rgb: [u8; 3], depth: f32, surface: Surface) {
        let index = self.level_index(u, v);
        self.level_surface[index] = surface;
        self.level[index] = rgb;
        self.depth[index] = depth;
    }

    /// Turns the level view into the camera image, rotating by the body's pitch and roll (nearest
    /// level pixel, as a native render would not blur), and adds the sensor noise.
    fn resample(&mut self, rotation: &Rotation, out: &mut RgbImage) {
        let (width, height) = (self.camera.width, self.camera.height);
        if out.width != width || out.height != height {
            *out = RgbImage::new(width, height);
        }
        let noise_offset = mix64(self.frame) as usize;
        let untilted = rotation.is_identity();
        let (max_u, max_v) = ((self.level_width - 1) as f32, (self.level_height - 1) as f32);
        for v in 0..height {
            let mut ray = rotation.row_start(v);
            let row = &mut out.data[v * width * 3..(v + 1) * width * 3];
            for (u, pixel) in row.chunks_exact_mut(3).enumerate() {
                let source = if untilted {
                    self.level_index(u + MARGIN_PX, v + MARGIN_PX)
                } else {
                    let (lu, lv) = rotation.project(ray);
                    ray = rotation.step_right(ray);
                    self.level_index((lu + 0.5).clamp(0.0, max_u) as usize, (lv + 0.5).clamp(0.0, max_v) as usize)
                };
                let rgb = self.level[source];
                self.surfaces[v * width + u] = self.level_surface[source];
                let noise = self.noise[(noise_offset + v * width + u) & NOISE_MASK] as i16;
                for k in 0..3 {
                    pixel[k] = (rgb[k] as i16 + noise).clamp(0, 255) as u8;
                }
            }
        }
    }
}

/// Where the pixels of the tilted camera are in the level view: a pure rotation, so a homography.
struct Rotation {
    base: [f64; 3],
    per_u: [f64; 3],
    per_v: [f64; 3],
    cx: f64,
    cy: f64,
    focal: f64,
}

impl Rotation {
    fn new(pose: &BodyPose, camera: &CameraModel) -> Self {
        let (cx, cy) = camera.principal_point();
        let focal = camera.focal_px;
        Rotation {
            base: tilt(pose, [1.0, 0.0, 0.0]),
            per_u: tilt(pose, [0.0, -1.0 / focal, 0.0]),
            per_v: tilt(pose, [0.0, 0.0, -1.0 / focal]),
            cx,
            cy,
            focal,
        }
    }

    /// True when pitch and roll move no pixel by more than a hundredth.
    fn is_identity(&self) -> bool {
        let corner = self.level_pixel(0, 0);
        let opposite = self.level_pixel((2.0 * self.cx) as usize, (2.0 * self.cy) as usize);
        (corner.0 - MARGIN_PX as f64).abs() < 0.01
            && (corner.1 - MARGIN_PX as f64).abs() < 0.01
            && (opposite.0 - 2.0 * self.cx - MARGIN_PX as f64).abs() < 0.01
            && (opposite.1 - 2.0 * self.cy - MARGIN_PX as f64).abs() < 0.01
    }

    /// Level-view coordinates of output pixel (u, v).
    fn level_pixel(&self, u: usize, v: usize) -> (f64, f64) {
        let (du, dv) = (u as f64 - self.cx, v as f64 - self.cy);
        let ray = [0, 1, 2].map(|k| self.base[k] + du * self.per_u[k] + dv * self.per_v[k]);
        let scale = self.focal / ray[0];
        (self.cx + MARGIN_PX as f64 - ray[1] * scale, self.cy + MARGIN_PX as f64 - ray[2] * scale)
    }

    /// The level-frame ray of the first pixel of output row `v`.
    fn row_start(&self, v: usize) -> [f32; 3] {
        let dv = v as f64 - self.cy;
        [0, 1, 2].map(|k| (self.base[k] - self.cx * self.per_u[k] + dv * self.per_v[k]) as f32)
    }

    /// The ray of the next pixel to the right.
    fn step_right(&self, ray: [f32; 3]) -> [f32; 3] {
        [ray[0] + self.per_u[0] as f32, ray[1] + self.per_u[1] as f32, ray[2] + self.per_u[2] as f32]
    }

    /// Level-view coordinates of a level-frame ray.
    fn project(&self, ray: [f32; 3]) -> (f32, f32) {
        let scale = self.focal as f32 / ray[0];
        ((self.cx + MARGIN_PX as f64) as f32 - ray[1] * scale, (self.cy + MARGIN_PX as f64) as f32 - ray[2] * scale)
    }
}

/// The first whole row at or below `row` (rows above the image give 0).
fn ceil_row(row: f64) -> usize {
    if row <= 0.0 {
        return 0;
    }
    let whole = row as usize;
    if (whole as f64) < row { whole + 1 } else { whole }
}

fn grid_coverage(x: f64, y: f64, depth: f64, view: &LevelView) -> f32 {
    let footprint = depth * depth / (view.focal * view.height.max(0.05)) + depth / view.focal;
    let coverage = |p: f64| {
        let distance = ((p - 0.5) - (p - 0.5).round()).abs();
        ((GRID_HALF_WIDTH_M + footprint * 0.5 - distance) / footprint).clamp(0.0, 1.0)
    };
    coverage(x).max(coverage(y)) as f32
}

fn fog(rgb: [f32; 3], distance: f64) -> [f32; 3] {
    let (visible, haze) = fog_weights(distance);
    [rgb[0] * visible + haze[0], rgb[1] * visible + haze[1], rgb[2] * visible + haze[2]]
}

/// Fog at `distance`: the weight of the surface colour and the fog colour already weighted.
fn fog_weights(distance: f64) -> (f32, [f32; 3]) {
    let visible = (-(FOG_DENSITY * distance).powi(2)).exp() as f32;
    (visible, scale3(FOG_RGB, 1.0 - visible))
}

fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t]
}

fn scale3(rgb: [f32; 3], factor: f32) -> [f32; 3] {
    [rgb[0] * factor, rgb[1] * factor, rgb[2] * factor]
}
