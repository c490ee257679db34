//! The samara property language (parser, checker, lowering, VNN-LIB) and the linear
//! normal form every query is lowered to ([`normal`]).

pub mod normal;
