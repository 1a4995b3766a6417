//! A core's ports of one kind (its input topics, its commands), kept in the order added and found
//! by name, as the graph table names them.

/// A port, known by the name of its topic or command.
pub(crate) trait Named {
    /// The topic's or the command's name, as in the tables.
    fn name(&self) -> &'static str;
}

/// Ports of one kind, in the order added.
pub(crate) struct Ports<P: ?Sized>(Vec<Box<P>>);

impl<P: ?Sized + Named> Ports<P> {
    pub(crate) fn push(&mut self, port: Box<P>) {
        self.0.push(port);
    }

    /// The names of the ports, in the order added.
    pub(crate) fn names(&self) -> Vec<&'static str> {
        self.0.iter().map(|port| port.name()).collect()
    }

    /// The port named `name`, if any.
    pub(crate) fn find(&self, name: &str) -> Option<&P> {
        self.0.iter().find(|port| port.name() == name).map(|port| &**port)
    }

    /// The ports, in the order added.
    pub(crate) fn iter(&self) -> impl Iterator<Item = &P> {
        self.0.iter().map(|port| &**port)
    }
}

impl<P: ?Sized> Default for Ports<P> {
    fn default() -> Self {
        Ports(Vec::new())
    }
}
