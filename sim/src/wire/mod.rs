//! The simulator's side of the wire: the Unity client's Socket.IO dialect.

pub mod client;
pub mod command;
pub mod packet;
pub mod telemetry;
