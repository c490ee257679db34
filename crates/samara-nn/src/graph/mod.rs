//! The graph IR: a network as a DAG of operators ([`crate::ops::Op`]) over tensors, for
//! networks that are not a chain of dense layers (convolutions, pooling, residual
//! blocks, the VNN-COMP operator set).
//!
//! [`import`] reads an ONNX model into a [`Graph`]: constants (initializers, `Constant`
//! nodes and every node computed from constants only, e.g. shape arithmetic) are folded
//! at import; every other node is evaluated once on zeros so that shapes are known and
//! checked. [`Graph::eval_f64`] evaluates the graph on one sample. [`lower`] turns a
//! piecewise-linear graph into the chain [`crate::Network`] the verifier reads (affine
//! maps each followed by ReLU).

pub mod import;
pub mod lower;

use crate::ops::{Op, Tensor};

/// A tensor of the graph: a constant, or computed from the input.
#[derive(Clone, Debug, PartialEq)]
pub struct Value {
    /// Name in the file.
    pub name: String,
    /// Shape (symbolic dimensions as 1: one sample is evaluated).
    pub shape: Vec<usize>,
    /// The values, for a constant.
    pub konst: Option<Tensor>,
}

/// One operator application.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Name in the file (or `#index (op)`).
    pub name: String,
    /// The ONNX operator name.
    pub op_type: String,
    /// The operator and its attributes.
    pub op: Op,
    /// Input values (`None`: an optional input left out).
    pub inputs: Vec<Option<usize>>,
    /// Output values.
    pub outputs: Vec<usize>,
}

/// A network as a DAG: one input tensor, one output tensor, nodes in topological order.
#[derive(Clone, Debug, PartialEq)]
pub struct Graph {
    /// Every tensor (constants and computed ones).
    pub values: Vec<Value>,
    /// The nodes computing the non-constant values, in order.
    pub nodes: Vec<Node>,
    /// The input value.
    pub input: usize,
    /// The output value.
    pub output: usize,
}

impl Graph {
    /// Number of input entries (the input tensor's, row-major).
    pub fn n_inputs(&self) -> usize {
        self.values[self.input].shape.iter().product()
    }

    /// Number of output entries.
    pub fn n_outputs(&self) -> usize {
        self.values[self.output].shape.iter().product()
    }

    /// Evaluate on one sample (the input tensor's entries, row-major); the output
    /// tensor's entries. `Err` names the node whose evaluation failed (only on an input
    /// of the wrong length: shapes are checked at import).
    pub fn eval_f64(&self, x: &[f64]) -> Result<Vec<f64>, String> {
        if x.len() != self.n_inputs() {
            return Err(format!(
                "the network has {} inputs, {} given",
                self.n_inputs(),
                x.len()
            ));
        }
        let mut slots: Vec<Option<Tensor>> = vec![None; self.values.len()];
        slots[self.input] = Some(Tensor::new(
            self.values[self.input].shape.clone(),
            x.to_vec(),
        ));
        for n in &self.nodes {
            let ins: Vec<Option<&Tensor>> = n
                .inputs
                .iter()
                .map(|i| i.and_then(|i| self.values[i].konst.as_ref().or(slots[i].as_ref())))
                .collect();
            let outs =
                n.op.eval(&ins)
                    .map_err(|e| format!("node `{}` ({}): {e}", n.name, n.op_type))?;
            for (o, t) in n.outputs.iter().zip(outs) {
                slots[*o] = Some(t);
            }
        }
        slots[self.output]
            .take()
            .map(|t| t.data)
            .ok_or_else(|| "the output was not computed".into())
    }

    /// Remove a final `Softmax` taken over all the output's entries at once (every
    /// other dimension 1, so ONNX's old flattening semantics and the per-axis one
    /// agree): the graph then computes the logits. `true` when it was removed.
    ///
    /// Softmax is strictly increasing in each logit against any other
    /// (`s_i >= s_j` iff `x_i >= x_j`), so a property that only compares two outputs
    /// with each other (VNN-COMP's classification properties `Y_i >= Y_j`) has the same
    /// answer on the logits; the caller checks the property is of that form.
    pub fn strip_final_softmax(&mut self) -> bool {
        let Some(last) = self.nodes.last() else {
            return false;
        };
        let Op::Softmax { axis } = last.op else {
            return false;
        };
        let (Some(Some(x)), [out]) = (last.inputs.first(), last.outputs.as_slice()) else {
            return false;
        };
        let shape = &self.values[*x].shape;
        let one_group = crate::ops::norm_axis(axis, shape.len())
            .map(|a| shape.iter().enumerate().all(|(k, &d)| k == a || d == 1))
            .unwrap_or(false);
        if *out != self.output || *x == self.input || !one_group {
            return false;
        }
        self.output = *x;
        self.nodes.pop();
        true
    }
}
