//! Missions: one run in one thread ([`in_process`]) or with every node in its own process
//! ([`in_graph`]), scored against the simulator's true world (`rover eval`, `rover demo`), with
//! where the time went, how the mission progressed and its picture.

pub mod chaos;
pub mod demo;
pub mod eval;
mod evaluator;
pub mod in_graph;
pub mod in_process;
pub mod picture;
pub mod time_by_mode;
pub mod timeline;
