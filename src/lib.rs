//! The `rover` application on top of the libraries and nodes: running missions and scoring them
//! ([`missions`]), starting and watching the graph's processes ([`processes`]), and the tools for
//! recordings, bags and the live view ([`tools`]).

pub mod missions;
pub mod processes;
pub mod tools;
