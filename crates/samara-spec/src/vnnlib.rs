//! VNN-LIB
