//! The headless rover simulator: a stand-in for the Unity "Search and Sample Return" simulator
//! that speaks its client's exact Socket.IO dialect ([`wire`]), renders the rover camera from a
//! world map ([`camera`]), simulates the rover ([`physics`]) and reports each run.

mod boulder;
pub mod camera;
pub mod cli;
pub mod distance;
pub mod elevation;
mod look;
mod obstacle;
mod physics;
pub mod procgen;
pub mod random;
pub mod render;
mod rock_survey;
pub mod sim;
mod start;
mod terrain;
pub mod unity_world;
pub mod wire;
pub mod world;
