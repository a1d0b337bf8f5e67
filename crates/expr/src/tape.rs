//! The formula as a tape for many parameter vectors at once — an unscented filter's sigma
//! points ([`ParamModel::eval_many`](physid_core::ParamModel::eval_many)).
//!
//! The tree is flattened into its distinct operations (a subexpression written several times —
//! `r*sin(q)/l` in a slider-crank term — is one operation, as it would be one `let` in a model
//! written in Rust), children before parents. Each operation has a register as wide as the
//! number of points: a parameter-free one (`sin(q)`, `w^2`) is computed once per call and
//! broadcast; the others run as one tight loop over the points, so the dispatch on the
//! operation is paid once per operation, not once per operation and point.
//!
//! The same operations on the same operands as [`ExprModel::eval`](crate::ExprModel): the
//! results equal its values bit for bit (tested).

use crate::parse::{ExprModel, Func, Node};
use physid_core::Scalar;
use std::cell::RefCell;
use std::collections::HashMap;

/// One distinct operation: a tree's node whose operands are earlier registers of the tape.
type Op = Node;

/// An operation's identity for merging repeats (a number by its bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Key {
    Num(u64),
    Param(usize),
    Input(usize),
    Unary(u8, u32, i32),
    Call(Func, u32),
    Binary(u8, u32, u32),
}

/// An operation's identity.
fn key(op: Op) -> Key {
    match op {
        Op::Num(v) => Key::Num(v.to_bits()),
        Op::Param(k) => Key::Param(k),
        Op::Input(k) => Key::Input(k),
        Op::Neg(a) => Key::Unary(0, a, 0),
        Op::PowI(a, n) => Key::Unary(1, a, n),
        Op::Call(f, a) => Key::Call(f, a),
        Op::Add(a, b) => Key::Binary(0, a, b),
        Op::Sub(a, b) => Key::Binary(1, a, b),
        Op::Mul(a, b) => Key::Binary(2, a, b),
        Op::Div(a, b) => Key::Binary(3, a, b),
        Op::Pow(a, b) => Key::Binary(4, a, b),
        Op::Min(a, b) => Key::Binary(5, a, b),
        Op::Max(a, b) => Key::Binary(6, a, b),
    }
}

/// A formula's distinct operations in evaluation order.
#[derive(Debug, Clone, Default)]
pub(crate) struct Tape {
    ops: Vec<Op>,
    /// Whether each operation depends on a parameter.
    dep: Vec<bool>,
    /// The operations that do, in order (the ones reverse mode walks back through).
    dep_ops: Vec<u32>,
    root: u32,
}

thread_local! {
    /// The registers, grown to the largest tape × points seen on this thread (then reused:
    /// no allocation per call).
    static REGISTERS: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
    /// The adjoints of [`Tape::value_and_gradient`] (each operation's, then each
    /// parameter's), grown likewise.
    static ADJOINTS: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// `x^y`, `x^e`, `x^n` as the scalar type defines them (for `f64`, the calls the generic
/// evaluation makes — not `f64`'s own methods of the same names).
#[inline(always)]
fn powd<T: Scalar>(x: T, y: T) -> T {
    x.powd(y)
}
#[inline(always)]
fn powf<T: Scalar>(x: T, e: f64) -> T {
    x.powf(e)
}
#[inline(always)]
fn powi<T: Scalar>(x: T, n: i32) -> T {
    x.powi(n)
}

/// `dst[j] = f(x[j])` over the points.
#[inline(always)]
fn map1(dst: &mut [f64], x: &[f64], f: impl Fn(f64) -> f64) {
    for (d, &x) in dst.iter_mut().zip(x) {
        *d = f(x);
    }
}

/// `dst[j] = f(x[j], y[j])` over the points.
#[inline(always)]
fn map2(dst: &mut [f64], x: &[f64], y: &[f64], f: impl Fn(f64, f64) -> f64) {
    for ((d, &x), &y) in dst.iter_mut().zip(x).zip(y) {
        *d = f(x, y);
    }
}

impl Tape {
    /// The tape of `m`'s tree: the nodes reachable from the root, repeats merged.
    pub(crate) fn new(m: &ExprModel) -> Self {
        // Children precede parents in `m.nodes`: mark what the root reaches, walking down.
        let mut used = vec![false; m.nodes.len()];
        used[m.root as usize] = true;
        for i in (0..m.nodes.len()).rev() {
            if used[i] {
                for c in m.nodes[i].children().into_iter().flatten() {
                    used[c as usize] = true;
                }
            }
        }
        let mut tape = Self::default();
        let mut seen: HashMap<Key, u32> = HashMap::new();
        let mut reg = vec![0u32; m.nodes.len()];
        for (i, node) in m.nodes.iter().enumerate() {
            if !used[i] {
                continue;
            }
            let op = node.with_children(|c| reg[c as usize]);
            reg[i] = *seen.entry(key(op)).or_insert_with(|| {
                tape.ops.push(op);
                tape.dep.push(m.dep[i]);
                (tape.ops.len() - 1) as u32
            });
        }
        tape.root = reg[m.root as usize];
        tape.dep_ops = (0..tape.ops.len() as u32)
            .filter(|&r| tape.dep[r as usize])
            .collect();
        tape
    }

    /// Distinct operations.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.ops.len()
    }

    /// The formula at inputs `u` for `out.len()` parameter vectors stored one after another in
    /// `params`, into `out`.
    pub(crate) fn eval_many(&self, u: &[f64], params: &[f64], out: &mut [f64]) {
        let n = out.len();
        if n == 0 {
            return;
        }
        let len = params.len() / n;
        REGISTERS.with(|cell| {
            let mut regs = cell.borrow_mut();
            if regs.len() < self.ops.len() * n {
                regs.resize(self.ops.len() * n, 0.0);
            }
            for (r, (&op, &dep)) in self.ops.iter().zip(&self.dep).enumerate() {
                let (done, rest) = regs.split_at_mut(r * n);
                let dst = &mut rest[..n];
                let at = |a: u32| &done[a as usize * n..(a as usize + 1) * n];
                if !dep {
                    // Parameter-free: once, at the first point's operands, then broadcast.
                    let v = self.scalar(op, u, |a| done[a as usize * n]);
                    dst.fill(v);
                    continue;
                }
                match op {
                    Op::Param(k) => {
                        for (j, d) in dst.iter_mut().enumerate() {
                            *d = params[j * len + k];
                        }
                    }
                    Op::Neg(a) => map1(dst, at(a), |x| -x),
                    Op::Add(a, b) => map2(dst, at(a), at(b), |x, y| x + y),
                    Op::Sub(a, b) => map2(dst, at(a), at(b), |x, y| x - y),
                    Op::Mul(a, b) => map2(dst, at(a), at(b), |x, y| x * y),
                    Op::Div(a, b) => map2(dst, at(a), at(b), |x, y| x / y),
                    Op::Pow(a, b) if self.dep[b as usize] => map2(dst, at(a), at(b), powd),
                    Op::Pow(a, b) => map2(dst, at(a), at(b), powf),
                    Op::PowI(a, 2) => map1(dst, at(a), |x| x * x),
                    Op::PowI(a, 3) => map1(dst, at(a), |x| x * x * x),
                    Op::PowI(a, n) => map1(dst, at(a), |x| powi(x, n)),
                    Op::Call(f, a) => match f {
                        Func::Sqrt => map1(dst, at(a), |x| Func::Sqrt.apply(x)),
                        Func::Sin => map1(dst, at(a), |x| Func::Sin.apply(x)),
                        Func::Cos => map1(dst, at(a), |x| Func::Cos.apply(x)),
                        Func::Abs => map1(dst, at(a), |x| Func::Abs.apply(x)),
                        Func::Exp => map1(dst, at(a), |x| Func::Exp.apply(x)),
                        f => map1(dst, at(a), |x| f.apply(x)),
                    },
                    Op::Min(a, b) => map2(dst, at(a), at(b), |x, y| if y < x { y } else { x }),
                    Op::Max(a, b) => map2(dst, at(a), at(b), |x, y| if y > x { y } else { x }),
                    // Leaves other than parameters depend on none.
                    Op::Num(_) | Op::Input(_) => {}
                }
            }
            let root = self.root as usize;
            out.copy_from_slice(&regs[root * n..(root + 1) * n]);
        });
    }

    /// The value and the exact gradient with respect to the parameters `free` at one
    /// parameter vector, by reverse mode: the operations forwards in `f64` (the value is
    /// [`eval_many`](Self::eval_many)'s, so the formula's own, bit for bit), then each
    /// operation's adjoint backwards through its local partials (`∂(a·b)/∂a = b`,
    /// `∂(a/b)/∂b = −(a/b)/b`, `∂aᵇ/∂b = aᵇ·ln a`, a function's [`Func::derivative`]). The cost is
    /// about two passes over the tape whatever the number of parameters — forward mode carries
    /// every partial through every operation. The partials equal forward mode's to round-off
    /// (sums in another order: a few units in the last place, tested).
    pub(crate) fn value_and_gradient(
        &self,
        u: &[f64],
        params: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64 {
        let n = self.ops.len();
        REGISTERS.with(|values| {
            ADJOINTS.with(|adjoints| {
                let (mut v, mut adj) = (values.borrow_mut(), adjoints.borrow_mut());
                if v.len() < n {
                    v.resize(n, 0.0);
                }
                if adj.len() < n + params.len() {
                    adj.resize(n + params.len(), 0.0);
                }
                for (r, &op) in self.ops.iter().enumerate() {
                    let (done, rest) = v.split_at_mut(r);
                    let at = |a: u32| done[a as usize];
                    rest[0] = match op {
                        Op::Param(k) => params[k],
                        Op::Pow(a, b) if self.dep[b as usize] => powd(at(a), at(b)),
                        _ => self.scalar(op, u, at),
                    };
                }
                let root = self.root as usize;
                if v[root].is_nan() {
                    // No gradient of an undefined value (a root of a negative number, say):
                    // every partial NaN, as forward mode gives it.
                    grad.fill(f64::NAN);
                    return v[root];
                }
                let (adj, adj_p) = adj.split_at_mut(n);
                adj.fill(0.0);
                adj_p.fill(0.0);
                adj[root] = 1.0;
                for &r in self.dep_ops.iter().rev() {
                    let r = r as usize;
                    let a = adj[r];
                    if a == 0.0 {
                        continue;
                    }
                    let dep = |i: u32| self.dep[i as usize];
                    let val = |i: u32| v[i as usize];
                    let mut add = |i: u32, d: f64| {
                        if dep(i) {
                            adj[i as usize] += d;
                        }
                    };
                    match self.ops[r] {
                        Op::Param(k) => adj_p[k] += a,
                        Op::Neg(x) => add(x, -a),
                        Op::Add(x, y) => {
                            add(x, a);
                            add(y, a);
                        }
                        Op::Sub(x, y) => {
                            add(x, a);
                            add(y, -a);
                        }
                        Op::Mul(x, y) => {
                            add(x, a * val(y));
                            add(y, a * val(x));
                        }
                        Op::Div(x, y) => {
                            // ∂(x/y)/∂x = 1/y, ∂(x/y)/∂y = −(x/y)/y: one division.
                            let q = a / val(y);
                            add(x, q);
                            add(y, -q * v[r]);
                        }
                        Op::Pow(x, y) => {
                            add(x, a * val(y) * powf(val(x), val(y) - 1.0));
                            add(y, a * v[r] * val(x).ln());
                        }
                        Op::PowI(x, k) => add(x, a * f64::from(k) * powi(val(x), k - 1)),
                        Op::Call(f, x) => add(x, a * f.derivative(val(x), v[r])),
                        Op::Min(x, y) => add(if val(y) < val(x) { y } else { x }, a),
                        Op::Max(x, y) => add(if val(y) > val(x) { y } else { x }, a),
                        Op::Num(_) | Op::Input(_) => {}
                    }
                }
                for (g, &j) in grad.iter_mut().zip(free) {
                    *g = adj_p[j];
                }
                v[root]
            })
        })
    }

    /// A parameter-free operation's value, its operands read through `at`.
    fn scalar(&self, op: Op, u: &[f64], at: impl Fn(u32) -> f64) -> f64 {
        match op {
            Op::Num(v) => v,
            Op::Input(k) => u[k],
            Op::Param(_) => f64::NAN, // a parameter is never parameter-free
            Op::Neg(a) => -at(a),
            Op::Add(a, b) => at(a) + at(b),
            Op::Sub(a, b) => at(a) - at(b),
            Op::Mul(a, b) => at(a) * at(b),
            Op::Div(a, b) => at(a) / at(b),
            Op::Pow(a, b) => powf(at(a), at(b)),
            Op::PowI(a, 2) => at(a) * at(a),
            Op::PowI(a, 3) => at(a) * at(a) * at(a),
            Op::PowI(a, n) => powi(at(a), n),
            Op::Call(f, a) => f.apply(at(a)),
            Op::Min(a, b) => {
                let (x, y) = (at(a), at(b));
                if y < x {
                    y
                } else {
                    x
                }
            }
            Op::Max(a, b) => {
                let (x, y) = (at(a), at(b));
                if y > x {
                    y
                } else {
                    x
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A subexpression written twice is one operation; the root is the last.
    #[test]
    fn repeats_are_one_operation() {
        let m = ExprModel::parse("A*x + A*x + sin(x)*sin(x)", &["A"]).unwrap();
        // A, x, A*x, A*x + A*x, sin(x), sin(x)*sin(x), the sum: 7 of the tree's 13 nodes.
        let t = Tape::new(&m);
        assert_eq!((m.nodes.len(), t.len()), (13, 7));
        assert_eq!(t.root as usize, t.len() - 1);
        let mut out = [0.0; 2];
        t.eval_many(&[0.5], &[2.0, 3.0], &mut out);
        let s = 0.5f64.sin();
        assert_eq!(out, [(1.0 + 1.0) + s * s, (1.5 + 1.5) + s * s]);
    }
}
