//! Pairs messages of two topics that belong together (same stamp or frame number), whichever
//! arrives first: the exact-time synchroniser of ROS `message_filters`, for two topics.

use std::collections::VecDeque;

/// Waiting messages of two streams, matched by key.
#[derive(Debug)]
pub struct Pairer<K, A, B> {
    first: VecDeque<(K, A)>,
    second: VecDeque<(K, B)>,
    capacity: usize,
    dropped: u64,
}

impl<K: PartialEq, A, B> Pairer<K, A, B> {
    /// A pairer keeping at most `capacity` unmatched messages per stream (the oldest go first).
    pub fn new(capacity: usize) -> Self {
        Pairer { first: VecDeque::new(), second: VecDeque::new(), capacity: capacity.max(1), dropped: 0 }
    }

    /// Messages dropped unmatched so far.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Adds a message of the first stream; returns the pair if its partner is already here.
    pub fn push_first(&mut self, key: K, message: A) -> Option<(A, B)> {
        pair_or_keep(&mut self.second, &mut self.first, (key, message), self.capacity, &mut self.dropped)
    }

    /// Adds a message of the second stream; returns the pair if its partner is already here.
    pub fn push_second(&mut self, key: K, message: B) -> Option<(A, B)> {
        let pair = pair_or_keep(&mut self.first, &mut self.second, (key, message), self.capacity, &mut self.dropped);
        pair.map(|(message, partner)| (partner, message))
    }
}

/// Takes the partner of the keyed `message` out of `partners` and returns both; without one,
/// keeps the message in `waiting` (at most `capacity`, the oldest dropped and counted in `dropped`).
fn pair_or_keep<K: PartialEq, T, P>(
    partners: &mut VecDeque<(K, P)>,
    waiting: &mut VecDeque<(K, T)>,
    (key, message): (K, T),
    capacity: usize,
    dropped: &mut u64,
) -> Option<(T, P)> {
    if let Some(index) = partners.iter().position(|(k, _)| *k == key) {
        return partners.remove(index).map(|(_, partner)| (message, partner));
    }
    if waiting.len() == capacity {
        waiting.pop_front();
        *dropped += 1;
    }
    waiting.push_back((key, message));
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_in_either_order_and_drops_the_oldest() {
        let mut pairer: Pairer<u64, &str, i32> = Pairer::new(2);
        assert_eq!(pairer.push_first(1, "a"), None);
        assert_eq!(pairer.push_second(1, 10), Some(("a", 10)));
        assert_eq!(pairer.push_second(2, 20), None);
        assert_eq!(pairer.push_first(2, "b"), Some(("b", 20)));
        pairer.push_first(3, "c");
        pairer.push_first(4, "d");
        pairer.push_first(5, "e");
        assert_eq!(pairer.dropped(), 1);
        assert_eq!(pairer.push_second(3, 30), None, "3 was dropped");
        assert_eq!(pairer.push_second(5, 50), Some(("e", 50)));
    }
}
