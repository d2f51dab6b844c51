//! A pickle reader for the subset of protocols 2-4 that PyTorch checkpoints
//! use. It runs no code: classes and calls become [`Value::Global`] and
//! [`Value::Call`] nodes for the caller to interpret.

use std::collections::HashMap;

/// A decoded pickle value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `None`.
    None,
    /// A boolean.
    Bool(bool),
    /// An integer (pickles of PyTorch checkpoints fit 64 bits).
    Int(i64),
    /// A float.
    Float(f64),
    /// A text string.
    Str(String),
    /// A byte string.
    Bytes(Vec<u8>),
    /// A tuple.
    Tuple(Vec<Value>),
    /// A list.
    List(Vec<Value>),
    /// A dict, in insertion order.
    Dict(Vec<(Value, Value)>),
    /// A class or function named by module and name.
    Global(String, String),
    /// `callable(*args)`, not evaluated.
    Call(Box<Value>, Vec<Value>),
    /// An object restored by `BUILD` with a state, not evaluated.
    Build(Box<Value>, Box<Value>),
    /// A persistent id (for PyTorch: a storage reference).
    Persistent(Box<Value>),
}

impl Value {
    /// The items of a tuple or list.
    pub fn items(&self) -> Option<&[Value]> {
        match self {
            Value::Tuple(v) | Value::List(v) => Some(v),
            _ => None,
        }
    }

    /// The integer, if this is one.
    pub fn int(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            _ => None,
        }
    }

    /// The string, if this is one.
    pub fn str(&self) -> Option<&str> {
        match self {
            Value::Str(s) => Some(s),
            _ => None,
        }
    }
}

/// What went wrong in a pickle, and where.
#[derive(Debug, thiserror::Error)]
#[error("pickle byte {offset}: {message}")]
pub struct PickleError {
    /// Offset of the opcode in the stream.
    pub offset: usize,
    /// The problem.
    pub message: String,
}

/// Reads one pickle from the start of `data`; returns the value and the
/// number of bytes it took (the next pickle, if any, starts there).
pub fn read_pickle(data: &[u8]) -> Result<(Value, usize), PickleError> {
    Machine {
        data,
        pos: 0,
        stack: Vec::new(),
        marks: Vec::new(),
        memo: HashMap::new(),
    }
    .run()
}

struct Machine<'a> {
    data: &'a [u8],
    pos: usize,
    stack: Vec<Value>,
    marks: Vec<usize>,
    memo: HashMap<u32, Value>,
}

impl Machine<'_> {
    fn fail<T>(&self, at: usize, message: impl Into<String>) -> Result<T, PickleError> {
        Err(PickleError {
            offset: at,
            message: message.into(),
        })
    }

    fn take(&mut self, n: usize) -> Result<&[u8], PickleError> {
        if self.data.len() - self.pos < n {
            return self.fail(self.pos, "truncated");
        }
        let bytes = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(bytes)
    }

    fn u8(&mut self) -> Result<u8, PickleError> {
        Ok(self.take(1)?[0])
    }

    fn le<const N: usize>(&mut self) -> Result<[u8; N], PickleError> {
        Ok(self.take(N)?.try_into().expect("N bytes"))
    }

    fn line(&mut self) -> Result<String, PickleError> {
        let rest = &self.data[self.pos..];
        let Some(end) = rest.iter().position(|&b| b == b'\n') else {
            return self.fail(self.pos, "unterminated line");
        };
        let text = String::from_utf8_lossy(&rest[..end]).into_owned();
        self.pos += end + 1;
        Ok(text)
    }

    fn text(&mut self, n: usize) -> Result<Value, PickleError> {
        let at = self.pos;
        let bytes = self.take(n)?.to_vec();
        match String::from_utf8(bytes) {
            Ok(s) => Ok(Value::Str(s)),
            Err(_) => self.fail(at, "string is not UTF-8"),
        }
    }

    fn pop(&mut self, at: usize) -> Result<Value, PickleError> {
        match self.stack.pop() {
            Some(v) => Ok(v),
            None => self.fail(at, "stack underflow"),
        }
    }

    fn pop_mark(&mut self, at: usize) -> Result<Vec<Value>, PickleError> {
        match self.marks.pop() {
            Some(m) if m <= self.stack.len() => Ok(self.stack.split_off(m)),
            _ => self.fail(at, "no mark"),
        }
    }

    fn top(&mut self, at: usize) -> Result<&mut Value, PickleError> {
        match self.stack.last_mut() {
            Some(v) => Ok(v),
            None => Err(PickleError {
                offset: at,
                message: "stack underflow".into(),
            }),
        }
    }

    fn push_items(&mut self, at: usize, items: Vec<Value>) -> Result<(), PickleError> {
        match self.top(at)? {
            Value::List(list) => {
                list.extend(items);
                Ok(())
            }
            _ => self.fail(at, "APPEND to a non-list"),
        }
    }

    fn set_items(&mut self, at: usize, items: Vec<Value>) -> Result<(), PickleError> {
        if !items.len().is_multiple_of(2) {
            return self.fail(at, "odd number of dict items");
        }
        match self.top(at)? {
            Value::Dict(dict) => {
                let mut it = items.into_iter();
                while let (Some(k), Some(v)) = (it.next(), it.next()) {
                    dict.push((k, v));
                }
                Ok(())
            }
            // A dict subclass made by a call (OrderedDict): record the items as
            // the call's state, which is what restoring it would do.
            Value::Call(_, args) => {
                let mut it = items.into_iter();
                let mut dict = Vec::new();
                while let (Some(k), Some(v)) = (it.next(), it.next()) {
                    dict.push((k, v));
                }
                match args.last_mut() {
                    Some(Value::Dict(d)) => d.extend(dict),
                    _ => args.push(Value::Dict(dict)),
                }
                Ok(())
            }
            _ => self.fail(at, "SETITEM on a non-dict"),
        }
    }

    fn run(mut self) -> Result<(Value, usize), PickleError> {
        loop {
            let at = self.pos;
            let op = self.u8()?;
            match op {
                0x80 => {
                    self.u8()?; // PROTO n
                }
                0x95 => {
                    self.le::<8>()?; // FRAME length
                }
                b'.' => {
                    let v = self.pop(at)?;
                    return Ok((v, self.pos));
                }
                b'(' => self.marks.push(self.stack.len()),
                b'N' => self.stack.push(Value::None),
                0x88 => self.stack.push(Value::Bool(true)),
                0x89 => self.stack.push(Value::Bool(false)),
                b'J' => {
                    let v = i32::from_le_bytes(self.le()?);
                    self.stack.push(Value::Int(v as i64));
                }
                b'K' => {
                    let v = self.u8()?;
                    self.stack.push(Value::Int(v as i64));
                }
                b'M' => {
                    let v = u16::from_le_bytes(self.le()?);
                    self.stack.push(Value::Int(v as i64));
                }
                0x8a => {
                    // LONG1: little-endian two's complement of n bytes.
                    let n = self.u8()? as usize;
                    let bytes = self.take(n)?.to_vec();
                    if n > 8 {
                        // Only PyTorch's magic number is this long; keep its bytes.
                        self.stack.push(Value::Bytes(bytes));
                    } else {
                        let mut buf = if bytes.last().is_some_and(|&b| b & 0x80 != 0) {
                            [0xff; 8]
                        } else {
                            [0; 8]
                        };
                        buf[..n].copy_from_slice(&bytes);
                        self.stack.push(Value::Int(i64::from_le_bytes(buf)));
                    }
                }
                b'G' => {
                    let v = f64::from_be_bytes(self.le()?);
                    self.stack.push(Value::Float(v));
                }
                b'X' => {
                    let n = u32::from_le_bytes(self.le()?) as usize;
                    let v = self.text(n)?;
                    self.stack.push(v);
                }
                0x8c => {
                    let n = self.u8()? as usize;
                    let v = self.text(n)?;
                    self.stack.push(v);
                }
                b'U' => {
                    let n = self.u8()? as usize;
                    let v = self.take(n)?.to_vec();
                    self.stack.push(Value::Bytes(v));
                }
                b'T' => {
                    let n = u32::from_le_bytes(self.le()?) as usize;
                    let v = self.take(n)?.to_vec();
                    self.stack.push(Value::Bytes(v));
                }
                b'C' => {
                    let n = self.u8()? as usize;
                    let v = self.take(n)?.to_vec();
                    self.stack.push(Value::Bytes(v));
                }
                b')' => self.stack.push(Value::Tuple(Vec::new())),
                b']' => self.stack.push(Value::List(Vec::new())),
                b'}' => self.stack.push(Value::Dict(Vec::new())),
                b't' => {
                    let items = self.pop_mark(at)?;
                    self.stack.push(Value::Tuple(items));
                }
                b'l' => {
                    let items = self.pop_mark(at)?;
                    self.stack.push(Value::List(items));
                }
                b'd' => {
                    let items = self.pop_mark(at)?;
                    self.stack.push(Value::Dict(Vec::new()));
                    self.set_items(at, items)?;
                }
                0x85..=0x87 => {
                    let n = (op - 0x84) as usize;
                    if self.stack.len() < n {
                        return self.fail(at, "stack underflow");
                    }
                    let items = self.stack.split_off(self.stack.len() - n);
                    self.stack.push(Value::Tuple(items));
                }
                b'a' => {
                    let v = self.pop(at)?;
                    self.push_items(at, vec![v])?;
                }
                b'e' => {
                    let items = self.pop_mark(at)?;
                    self.push_items(at, items)?;
                }
                b's' => {
                    let v = self.pop(at)?;
                    let k = self.pop(at)?;
                    self.set_items(at, vec![k, v])?;
                }
                b'u' => {
                    let items = self.pop_mark(at)?;
                    self.set_items(at, items)?;
                }
                b'c' => {
                    let module = self.line()?;
                    let name = self.line()?;
                    self.stack.push(Value::Global(module, name));
                }
                0x93 => {
                    let name = self.pop(at)?;
                    let module = self.pop(at)?;
                    match (module, name) {
                        (Value::Str(m), Value::Str(n)) => self.stack.push(Value::Global(m, n)),
                        _ => return self.fail(at, "STACK_GLOBAL needs two strings"),
                    }
                }
                b'R' | 0x81 => {
                    let args = self.pop(at)?;
                    let callable = self.pop(at)?;
                    let Value::Tuple(args) = args else {
                        return self.fail(at, "call arguments are not a tuple");
                    };
                    self.stack.push(Value::Call(Box::new(callable), args));
                }
                b'b' => {
                    let state = self.pop(at)?;
                    let obj = self.pop(at)?;
                    self.stack
                        .push(Value::Build(Box::new(obj), Box::new(state)));
                }
                b'Q' => {
                    let id = self.pop(at)?;
                    self.stack.push(Value::Persistent(Box::new(id)));
                }
                b'q' => {
                    let i = self.u8()? as u32;
                    let v = self.top(at)?.clone();
                    self.memo.insert(i, v);
                }
                b'r' => {
                    let i = u32::from_le_bytes(self.le()?);
                    let v = self.top(at)?.clone();
                    self.memo.insert(i, v);
                }
                0x94 => {
                    let i = self.memo.len() as u32;
                    let v = self.top(at)?.clone();
                    self.memo.insert(i, v);
                }
                b'h' | b'j' => {
                    let i = if op == b'h' {
                        self.u8()? as u32
                    } else {
                        u32::from_le_bytes(self.le()?)
                    };
                    match self.memo.get(&i) {
                        Some(v) => self.stack.push(v.clone()),
                        None => return self.fail(at, format!("memo {i} is empty")),
                    }
                }
                b'0' => {
                    self.pop(at)?;
                }
                _ => return self.fail(at, format!("unsupported opcode 0x{op:02x}")),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_opcodes_checkpoints_use() {
        // Protocol 2: an OrderedDict() with {"a": (1, -2, 300, True, None), "b": [1.5]}.
        let mut p = vec![0x80, 2];
        p.extend(b"ccollections\nOrderedDict\nq\x00)R(X\x01\x00\x00\x00a");
        p.extend([b'(', b'K', 1, b'J']);
        p.extend((-2i32).to_le_bytes());
        p.extend([b'M']);
        p.extend(300u16.to_le_bytes());
        p.extend([0x88, b'N', b't', 0x8c, 1, b'b', b']', b'G']);
        p.extend(1.5f64.to_be_bytes());
        p.extend([b'a', b'u', b'.']);
        let (v, used) = read_pickle(&p).unwrap();
        assert_eq!(used, p.len());
        let Value::Call(callable, args) = v else {
            panic!("{v:?}")
        };
        assert_eq!(
            *callable,
            Value::Global("collections".into(), "OrderedDict".into())
        );
        assert_eq!(
            args,
            vec![Value::Dict(vec![
                (
                    Value::Str("a".into()),
                    Value::Tuple(vec![
                        Value::Int(1),
                        Value::Int(-2),
                        Value::Int(300),
                        Value::Bool(true),
                        Value::None
                    ])
                ),
                (Value::Str("b".into()), Value::List(vec![Value::Float(1.5)])),
            ])]
        );
    }

    #[test]
    fn long_integers_memo_and_errors() {
        // LONG1 of -1 (one byte 0xff), memoised and fetched twice.
        let (v, _) = read_pickle(&[0x8a, 1, 0xff, b'q', 7, b'0', b'h', 7, b'.']).unwrap();
        assert_eq!(v, Value::Int(-1));
        let err = read_pickle(&[0x80, 2, b'K']).unwrap_err();
        assert!(err.to_string().contains("truncated"), "{err}");
        let err = read_pickle(&[b'h', 3, b'.']).unwrap_err();
        assert!(err.to_string().contains("memo 3"), "{err}");
        assert!(read_pickle(&[0xff])
            .unwrap_err()
            .to_string()
            .contains("unsupported opcode"));
    }
}
