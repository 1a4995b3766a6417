//! The graph's processes: the node list, starting and restarting them, bringing managed nodes up, the CPU they take, how
//! steadily the machine runs, and an emulated network link between two hosts.

pub mod cpu;
pub mod graph;
pub mod lifecycle_manager;
pub mod link;
pub mod nodes;
pub mod steadiness;
