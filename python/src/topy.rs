//! A serde `Serializer` that builds Python objects straight from a typed result: structs
//! and maps become dicts (field name -> value), sequences and tuples lists, unit enum
//! variants their name, and numbers stay numbers. No JSON is written or parsed on the
//! way, so a non-finite float (an unbounded enclosure's `inf`, a `NaN`) reaches Python
//! as that float, not as the `null` of a JSON document. The `samara` package turns these
//! into its frozen result classes.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use pyo3::BoundObject;
use serde::ser::{self, Serialize};
use std::fmt::Display;

/// The Python object of a typed value (see the module's comment).
pub fn to_py<T: Serialize + ?Sized>(py: Python<'_>, v: &T) -> PyResult<PyObject> {
    v.serialize(ToPy { py }).map_err(|e| e.0)
}

/// A failed conversion (a Python error, or a serde message as `ValueError`).
pub struct Error(PyErr);

impl std::fmt::Debug for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}

impl Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}

impl std::error::Error for Error {}

impl ser::Error for Error {
    fn custom<M: Display>(m: M) -> Self {
        Error(PyValueError::new_err(m.to_string()))
    }
}

impl From<PyErr> for Error {
    fn from(e: PyErr) -> Self {
        Error(e)
    }
}

type R = Result<PyObject, Error>;

/// A Python object of a Rust value.
fn obj<'py, T>(py: Python<'py>, v: T) -> R
where
    T: IntoPyObject<'py>,
    T::Error: Into<PyErr>,
{
    Ok(v.into_pyobject(py)
        .map_err(Into::into)?
        .into_bound()
        .into_any()
        .unbind())
}

#[derive(Clone, Copy)]
struct ToPy<'py> {
    py: Python<'py>,
}

/// A list being built (sequences, tuples; `variant`: the enum variant it is wrapped in).
struct Seq<'py> {
    py: Python<'py>,
    items: Vec<PyObject>,
    variant: Option<&'static str>,
}

/// A dict being built (maps, structs; `variant`: the enum variant it is wrapped in).
struct Map<'py> {
    py: Python<'py>,
    dict: Bound<'py, PyDict>,
    key: Option<PyObject>,
    variant: Option<&'static str>,
}

/// `{variant: value}`, serde's external tagging of a variant with data.
fn tagged(py: Python<'_>, variant: Option<&'static str>, value: PyObject) -> R {
    match variant {
        None => Ok(value),
        Some(v) => {
            let d = PyDict::new(py);
            d.set_item(v, value)?;
            Ok(d.into_any().unbind())
        }
    }
}

impl<'py> ser::Serializer for ToPy<'py> {
    type Ok = PyObject;
    type Error = Error;
    type SerializeSeq = Seq<'py>;
    type SerializeTuple = Seq<'py>;
    type SerializeTupleStruct = Seq<'py>;
    type SerializeTupleVariant = Seq<'py>;
    type SerializeMap = Map<'py>;
    type SerializeStruct = Map<'py>;
    type SerializeStructVariant = Map<'py>;

    fn serialize_bool(self, v: bool) -> R {
        obj(self.py, v)
    }
    fn serialize_i8(self, v: i8) -> R {
        obj(self.py, v)
    }
    fn serialize_i16(self, v: i16) -> R {
        obj(self.py, v)
    }
    fn serialize_i32(self, v: i32) -> R {
        obj(self.py, v)
    }
    fn serialize_i64(self, v: i64) -> R {
        obj(self.py, v)
    }
    fn serialize_u8(self, v: u8) -> R {
        obj(self.py, v)
    }
    fn serialize_u16(self, v: u16) -> R {
        obj(self.py, v)
    }
    fn serialize_u32(self, v: u32) -> R {
        obj(self.py, v)
    }
    fn serialize_u64(self, v: u64) -> R {
        obj(self.py, v)
    }
    fn serialize_f32(self, v: f32) -> R {
        obj(self.py, f64::from(v))
    }
    fn serialize_f64(self, v: f64) -> R {
        obj(self.py, v)
    }
    fn serialize_char(self, v: char) -> R {
        obj(self.py, v.to_string())
    }
    fn serialize_str(self, v: &str) -> R {
        obj(self.py, v)
    }
    fn serialize_bytes(self, v: &[u8]) -> R {
        obj(self.py, v.to_vec())
    }
    fn serialize_none(self) -> R {
        Ok(self.py.None())
    }
    fn serialize_some<T: Serialize + ?Sized>(self, v: &T) -> R {
        v.serialize(self)
    }
    fn serialize_unit(self) -> R {
        Ok(self.py.None())
    }
    fn serialize_unit_struct(self, _: &'static str) -> R {
        Ok(self.py.None())
    }
    fn serialize_unit_variant(self, _: &'static str, _: u32, variant: &'static str) -> R {
        obj(self.py, variant)
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, _: &'static str, v: &T) -> R {
        v.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        v: &T,
    ) -> R {
        let inner = v.serialize(self)?;
        tagged(self.py, Some(variant), inner)
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<Seq<'py>, Error> {
        Ok(Seq {
            py: self.py,
            items: Vec::with_capacity(len.unwrap_or(0)),
            variant: None,
        })
    }
    fn serialize_tuple(self, len: usize) -> Result<Seq<'py>, Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(self, _: &'static str, len: usize) -> Result<Seq<'py>, Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<Seq<'py>, Error> {
        let mut s = self.serialize_seq(Some(len))?;
        s.variant = Some(variant);
        Ok(s)
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Map<'py>, Error> {
        Ok(Map {
            py: self.py,
            dict: PyDict::new(self.py),
            key: None,
            variant: None,
        })
    }
    fn serialize_struct(self, _: &'static str, len: usize) -> Result<Map<'py>, Error> {
        self.serialize_map(Some(len))
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<Map<'py>, Error> {
        let mut m = self.serialize_map(Some(len))?;
        m.variant = Some(variant);
        Ok(m)
    }
}

impl Seq<'_> {
    fn push<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        self.items.push(v.serialize(ToPy { py: self.py })?);
        Ok(())
    }
    fn done(self) -> R {
        let list = PyList::new(self.py, self.items)?.into_any().unbind();
        tagged(self.py, self.variant, list)
    }
}

/// The four list-building traits of serde, each pushing its elements.
macro_rules! seq_impls {
    ($($tr:ident :: $m:ident),*) => {$(
        impl ser::$tr for Seq<'_> {
            type Ok = PyObject;
            type Error = Error;
            fn $m<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
                self.push(v)
            }
            fn end(self) -> R {
                self.done()
            }
        }
    )*};
}

seq_impls!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

impl Map<'_> {
    fn field<T: Serialize + ?Sized>(&mut self, k: &'static str, v: &T) -> Result<(), Error> {
        self.dict.set_item(k, v.serialize(ToPy { py: self.py })?)?;
        Ok(())
    }
    fn done(self) -> R {
        tagged(self.py, self.variant, self.dict.into_any().unbind())
    }
}

impl ser::SerializeMap for Map<'_> {
    type Ok = PyObject;
    type Error = Error;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, k: &T) -> Result<(), Error> {
        self.key = Some(k.serialize(ToPy { py: self.py })?);
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        let k = self
            .key
            .take()
            .ok_or_else(|| <Error as ser::Error>::custom("a map value without its key"))?;
        self.dict.set_item(k, v.serialize(ToPy { py: self.py })?)?;
        Ok(())
    }
    fn end(self) -> R {
        self.done()
    }
}

/// The two struct-building traits of serde, each setting a field.
macro_rules! struct_impls {
    ($($tr:ident),*) => {$(
        impl ser::$tr for Map<'_> {
            type Ok = PyObject;
            type Error = Error;
            fn serialize_field<T: Serialize + ?Sized>(
                &mut self,
                k: &'static str,
                v: &T,
            ) -> Result<(), Error> {
                self.field(k, v)
            }
            fn end(self) -> R {
                self.done()
            }
        }
    )*};
}

struct_impls!(SerializeStruct, SerializeStructVariant);
