//! The Socket.IO bridge between the rover simulator and the ROS 2 graph.
//!
//! [`telemetry`] parses the simulator's dialect, [`lockstep`] answers every frame exactly once,
//! [`server`] speaks Socket.IO to the simulator behind the [`gate`] that applies the [`access`]
//! rules, [`insets`] says which inset images a reply
//! carries, [`convert`] builds the ROS messages, [`clock`] counts simulated time and [`node`] is
//! the node's core, which the runtime's adapter runs beside the server; [`direct`] is the same
//! link to a simulator in the same process.

mod access;
mod clock;
pub mod convert;
pub mod direct;
mod gate;
mod insets;
mod lockstep;
pub mod node;
mod reply;
mod server;
mod sio;
pub mod stats;
pub mod telemetry;
mod teleop;
