//! Records handed to another thread in batches of [`BATCH`], the emptied
//! vectors coming back for reuse: replay's parser, its pipeline and its
//! writer, and the MCAP writer, each on its own thread, keep the order of
//! what they pass on and allocate only while the pool fills.

use std::sync::mpsc::{Receiver, SyncSender};

/// Records per batch.
pub const BATCH: usize = 8192;

/// The sending side: the batch being filled, the channel to the receiving
/// thread and the one its emptied vectors come back on.
pub struct Batches<T> {
    cur: Vec<T>,
    tx: Option<SyncSender<Vec<T>>>,
    back: Receiver<Vec<T>>,
}

impl<T> Batches<T> {
    pub fn new(tx: SyncSender<Vec<T>>, back: Receiver<Vec<T>>) -> Batches<T> {
        Batches { cur: Vec::with_capacity(BATCH), tx: Some(tx), back }
    }

    /// Adds one record, sending the batch when it is full. False once the
    /// receiving thread has gone (it stopped on an error, which it reports
    /// itself, or it was never going to read more).
    pub fn push(&mut self, r: T) -> bool {
        self.cur.push(r);
        self.cur.len() < BATCH || self.flush()
    }

    /// Sends what has been collected; false once the receiver has gone.
    pub fn flush(&mut self) -> bool {
        if self.cur.is_empty() {
            return self.tx.is_some();
        }
        let next = self.back.try_recv().unwrap_or_else(|_| Vec::with_capacity(BATCH));
        let batch = std::mem::replace(&mut self.cur, next);
        match &self.tx {
            Some(tx) if tx.send(batch).is_ok() => true,
            _ => {
                self.tx = None;
                false
            }
        }
    }

    /// Closes the channel (without sending what is left): the receiving
    /// thread's loop ends.
    pub fn close(&mut self) {
        self.tx = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_arrive_whole_in_order_and_a_gone_receiver_is_told() {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<u32>>(4);
        let (_back_tx, back) = std::sync::mpsc::sync_channel::<Vec<u32>>(8);
        let mut b = Batches::new(tx, back);
        let n = BATCH as u32 + 5;
        let h = std::thread::spawn(move || rx.into_iter().map(|v| v.len()).collect::<Vec<_>>());
        for i in 0..n {
            assert!(b.push(i));
        }
        assert!(b.flush());
        b.close();
        assert_eq!(h.join().unwrap(), vec![BATCH, 5]);
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<u32>>(4);
        let (_back_tx, back) = std::sync::mpsc::sync_channel::<Vec<u32>>(8);
        drop(rx);
        let mut b = Batches::new(tx, back);
        assert!(b.push(1) && !b.flush() && !b.flush());
    }
}
