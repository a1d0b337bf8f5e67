//! Where a stream stage's outputs go: [`Sink`] takes them one by one (a `Vec` is one). The
//! stages of every crate hand their outputs to it; `physid_apps::stage::Stage` is the shape of
//! a stage over a recording's chunks.

/// Where a stage's outputs go.
pub trait Sink<T> {
    /// Take one output.
    fn put(&mut self, item: T);
}

impl<T> Sink<T> for Vec<T> {
    fn put(&mut self, item: T) {
        self.push(item);
    }
}
