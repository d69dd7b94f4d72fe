//! The spool's pending moves (issue 26): each change of the valve's electrical signal reaches the spool
//! after a delay, and is held here until it arrives. Part of the valve's state ([`crate::ValveState`]); the
//! spool law that schedules and applies them is [`crate::spool`].

/// Pending moves a valve state holds at most: 32 changes of the electrical signal inside one delay (a
/// proportional valve commanded every 1 ms holds 32 ms of dead time). Beyond, the newest pending move takes
/// the newest change's value and keeps its own arrival (the change arrives early by one command period).
pub(crate) const CAPACITY: usize = 32;

/// The spool's pending moves: `(arrival time s, target)`, in order of arrival.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct PendingMoves {
    /// Whether the signal has been seen once.
    pub(crate) started: bool,
    /// Level of the electrical signal after the last change scheduled.
    pub(crate) electrical: f64,
    /// Target of the last move that arrived.
    pub(crate) target: f64,
    /// Number of pending moves.
    pub(crate) len: usize,
    /// The pending moves, `moves[..len]`.
    pub(crate) moves: [(f64, f64); CAPACITY],
}

impl PendingMoves {
    pub(crate) fn begin(&mut self, electrical: f64, target: f64) {
        *self = Self {
            started: true,
            electrical,
            target,
            ..Self::default()
        };
    }

    /// Schedules a move to `target` arriving at `arrival`; pending moves arriving no earlier are overtaken.
    pub(crate) fn push(&mut self, arrival: f64, target: f64) {
        while self.len > 0 && self.moves[self.len - 1].0 >= arrival {
            self.len -= 1;
        }
        let arrival = if self.len == CAPACITY {
            self.len -= 1;
            self.moves[CAPACITY - 1].0
        } else {
            arrival
        };
        let before = if self.len > 0 {
            self.moves[self.len - 1].1
        } else {
            self.target
        };
        if target != before {
            self.moves[self.len] = (arrival, target);
            self.len += 1;
        }
    }

    /// Applies every move that arrived by `t`.
    pub(crate) fn arrive(&mut self, t: f64) {
        let n = self.moves[..self.len]
            .iter()
            .take_while(|m| m.0 <= t)
            .count();
        if n > 0 {
            self.target = self.moves[n - 1].1;
            self.moves.copy_within(n..self.len, 0);
            self.len -= n;
        }
    }

    pub(crate) fn next_arrival(&self) -> Option<f64> {
        (self.len > 0).then(|| self.moves[0].0)
    }
}
