//! Two values of which one is current and the other is being prepared: a step or a guard
//! evaluation writes its candidate into the spare in place and, when it is kept, the two
//! swap roles. On the Cortex-M4 this saves the copy of a kept candidate (a solution is
//! ~300 bytes, an evaluation ~600) on every control tick.

/// The current value and the spare.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct DoubleBuffer<X> {
    slots: [X; 2],
    /// `slots[1]` is the current one.
    second: bool,
}

impl<X> DoubleBuffer<X> {
    /// `current` current, `spare` the spare.
    pub(crate) fn new(current: X, spare: X) -> Self {
        DoubleBuffer {
            slots: [current, spare],
            second: false,
        }
    }

    /// The current value.
    pub(crate) fn current(&self) -> &X {
        let [a, b] = &self.slots;
        if self.second {
            b
        } else {
            a
        }
    }

    /// The spare.
    pub(crate) fn spare(&self) -> &X {
        let [a, b] = &self.slots;
        if self.second {
            a
        } else {
            b
        }
    }

    /// The spare, to write a candidate into.
    pub(crate) fn spare_mut(&mut self) -> &mut X {
        let [a, b] = &mut self.slots;
        if self.second {
            a
        } else {
            b
        }
    }

    /// The spare becomes the current value.
    pub(crate) fn swap(&mut self) {
        self.second = !self.second;
    }
}
