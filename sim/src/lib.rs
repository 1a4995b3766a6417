//! The headless rover simulator: a stand-in for the Unity "Search and Sample Return" simulator
//! that speaks its client's exact Socket.IO dialect ([`wire`]), renders the rover camera from a
//! world map ([`camera`]), simulates the rover ([`physics`]) and reports each run.

pub mod boulder;
pub mod camera;
pub mod cli;
pub mod distance;
pub mod elevation;
pub mod look;
pub mod obstacle;
pub mod physics;
pub mod procgen;
pub mod random;
pub mod render;
pub mod rock_survey;
pub mod sim;
pub mod terrain;
pub mod unity_world;
pub mod wire;
pub mod world;
