//! The description's expressions over its parameters as graph nodes, per design: a sampled
//! parameter is a column of the `parameters` input `[B, P]`, a fixed one a constant, a derived
//! one its own expression. A part that reads no sampled parameter is folded to a constant with
//! the description's own evaluation ([`Expr::eval`]); the rest is the same IEEE double
//! arithmetic in the same order, so a value agrees with the product's to the last bits the
//! runtime's `Pow`, `Exp`, ... give.

use crate::graph::{Graph, Value};
use crate::{Error, Result};
use mbd_system::expr::{Expr, Func, Op};
use mbd_system::system::ParamSource;
use mbd_system::System;
use std::collections::HashMap;

/// A compiled expression: a constant, or a `[B]` value of the graph.
#[derive(Debug, Clone, PartialEq)]
pub enum Compiled {
    /// The same for every design.
    Const(f64),
    /// Per design, shape `[B]`.
    Node(Value),
}

impl Compiled {
    /// The value as a graph value (a constant becomes a scalar initializer).
    pub fn value(&self, g: &mut Graph) -> Value {
        match self {
            Compiled::Const(v) => g.scalar(*v),
            Compiled::Node(n) => n.clone(),
        }
    }
}

/// Compiles expressions of one system against the `parameters` input.
pub struct Expressions<'a> {
    system: &'a System,
    params: Value,
    nominal: Vec<f64>,
    sampled: HashMap<usize, usize>,
    cache: HashMap<usize, Compiled>,
}

impl<'a> Expressions<'a> {
    /// Expressions of `system` over the graph input `params` (`[B, P]`, the sampled
    /// parameters in the description's order).
    pub fn new(system: &'a System, params: Value) -> Result<Self> {
        let nominal = system
            .values(&system.nominal())
            .map_err(|e| Error::Unsupported(format!("the description's nominal design: {e}")))?;
        let sampled = system
            .sampled()
            .into_iter()
            .enumerate()
            .map(|(k, i)| (i, k))
            .collect();
        Ok(Self {
            system,
            params,
            nominal,
            sampled,
            cache: HashMap::new(),
        })
    }

    /// Whether `e` reads a sampled parameter (directly or through derived ones).
    fn varies(&self, e: &Expr) -> bool {
        e.parameters()
            .iter()
            .any(|i| match &self.system.parameters[*i].source {
                ParamSource::Sampled { .. } => true,
                ParamSource::Fixed(_) => false,
                ParamSource::Derived(d) => self.varies(d),
            })
    }

    /// `e` per design.
    pub fn compile(&mut self, g: &mut Graph, e: &Expr) -> Result<Compiled> {
        if !self.varies(e) {
            return Ok(Compiled::Const(e.eval(&self.nominal)));
        }
        Ok(Compiled::Node(match e {
            Expr::Num(v) => return Ok(Compiled::Const(*v)),
            Expr::Var(name, id) => {
                let i =
                    id.ok_or_else(|| Error::Unsupported(format!("unresolved name `{name}`")))?;
                return self.parameter(g, i);
            }
            Expr::Neg(a) => {
                let a = self.compile(g, a)?.value(g);
                g.unary("Neg", &a)
            }
            Expr::Bin(op, a, b) => {
                let (a, b) = (self.compile(g, a)?.value(g), self.compile(g, b)?.value(g));
                let name = match op {
                    Op::Add => "Add",
                    Op::Sub => "Sub",
                    Op::Mul => "Mul",
                    Op::Div => "Div",
                    Op::Pow => "Pow",
                };
                g.op(name, &[&a, &b], &[])
            }
            Expr::Call(f, args) => {
                let mut vals = Vec::with_capacity(args.len());
                for a in args {
                    vals.push(self.compile(g, a)?.value(g));
                }
                let name = match f {
                    Func::Sqrt => "Sqrt",
                    Func::Abs => "Abs",
                    Func::Exp => "Exp",
                    Func::Ln => "Log",
                    Func::Sin => "Sin",
                    Func::Cos => "Cos",
                    Func::Min => "Min",
                    Func::Max => "Max",
                };
                let refs: Vec<&str> = vals.iter().map(String::as_str).collect();
                g.op(name, &refs, &[])
            }
        }))
    }

    /// Parameter `i` of the table per design.
    fn parameter(&mut self, g: &mut Graph, i: usize) -> Result<Compiled> {
        if let Some(c) = self.cache.get(&i) {
            return Ok(c.clone());
        }
        let c = match &self.system.parameters[i].source {
            ParamSource::Fixed(v) => Compiled::Const(*v),
            ParamSource::Sampled { .. } => {
                let column = g.gather(&self.params, 1, &[self.sampled[&i] as i64]);
                Compiled::Node(g.reshape(&column, &[-1]))
            }
            ParamSource::Derived(e) => self.compile(g, &e.clone())?,
        };
        self.cache.insert(i, c.clone());
        Ok(c)
    }
}
