//! The glider's engine: zonotopes in the initial-set parameters, the network bounded
//! over each zonotope by CROWN ([`netstep`]), the plant flown by validated Taylor
//! integration in Lohner's form ([`flow`]), and the driver that cuts the initial set
//! into sub-boxes and refines them ([`driver`]).

pub mod driver;
pub mod flow;
pub mod netstep;
mod set;

pub use set::Zonotope;
