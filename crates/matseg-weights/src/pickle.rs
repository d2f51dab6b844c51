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

/// How deeply values may nest. A checkpoint's values nest a dozen levels;
/// much deeper ones (a byte a level makes them) would overflow the stack
/// of whatever walks them, dropping, comparing or printing them included.
pub const MAX_DEPTH: usize = 256;

/// The bytes of values the memo may copy (each value stored in it, and
/// each fetched from it, is a copy), beyond 16 per byte of the pickle: a
/// checkpoint's memo holds small values (class names, strings, tuples of a
/// tensor's size), while a few bytes that fetch a value twice and store
/// the pair would double it at each step.
pub const MEMO_COPY_ALLOWANCE: usize = 64 << 20;

/// Reads one pickle from the start of `data`; returns the value and the
/// number of bytes it took (the next pickle, if any, starts there). Values
/// nested deeper than [`MAX_DEPTH`], or memo copies past
/// [`MEMO_COPY_ALLOWANCE`], are errors.
pub fn read_pickle(data: &[u8]) -> Result<(Value, usize), PickleError> {
    Machine {
        data,
        pos: 0,
        stack: Vec::new(),
        sizes: Vec::new(),
        marks: Vec::new(),
        memo: HashMap::new(),
        copied: 0,
        copy_limit: MEMO_COPY_ALLOWANCE.saturating_add(data.len().saturating_mul(16)),
    }
    .run()
}

/// How deeply a value nests and about how many bytes it holds.
#[derive(Clone, Copy, Debug)]
struct Size {
    depth: usize,
    bytes: usize,
}

/// The bytes of one value, besides what it holds.
const NODE: usize = std::mem::size_of::<Value>();

impl Size {
    /// A value holding no others, and `payload` bytes.
    fn leaf(payload: usize) -> Self {
        Size {
            depth: 1,
            bytes: NODE + payload,
        }
    }

    /// A value holding values of `sizes`.
    fn holding(sizes: &[Size]) -> Self {
        Size {
            depth: 1 + sizes.iter().map(|s| s.depth).max().unwrap_or(0),
            bytes: NODE + sizes.iter().map(|s| s.bytes).sum::<usize>(),
        }
    }

    /// This value with the values `more` holds (a [`Size::holding`] them)
    /// put in it.
    fn adding(self, more: Size) -> Self {
        Size {
            depth: self.depth.max(more.depth),
            bytes: (self.bytes + more.bytes).saturating_sub(NODE),
        }
    }
}

struct Machine<'a> {
    data: &'a [u8],
    pos: usize,
    stack: Vec<Value>,
    /// The size of each value of `stack`.
    sizes: Vec<Size>,
    marks: Vec<usize>,
    memo: HashMap<u32, (Value, Size)>,
    /// Bytes of values copied into and out of the memo so far.
    copied: usize,
    /// The most that may be.
    copy_limit: usize,
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

    /// Pushes a value of `size`, refusing one nested too deeply.
    fn push(&mut self, at: usize, value: Value, size: Size) -> Result<(), PickleError> {
        if size.depth > MAX_DEPTH {
            return self.fail(at, format!("values nested deeper than {MAX_DEPTH} levels"));
        }
        self.stack.push(value);
        self.sizes.push(size);
        Ok(())
    }

    /// Pushes a value that holds no others.
    fn push_leaf(&mut self, at: usize, value: Value) -> Result<(), PickleError> {
        let payload = match &value {
            Value::Str(s) => s.len(),
            Value::Bytes(b) => b.len(),
            Value::Global(m, n) => m.len() + n.len(),
            _ => 0,
        };
        self.push(at, value, Size::leaf(payload))
    }

    fn pop(&mut self, at: usize) -> Result<(Value, Size), PickleError> {
        match (self.stack.pop(), self.sizes.pop()) {
            (Some(v), Some(s)) => Ok((v, s)),
            _ => self.fail(at, "stack underflow"),
        }
    }

    /// The values above the last mark, and the size of a value holding them.
    fn pop_mark(&mut self, at: usize) -> Result<(Vec<Value>, Size), PickleError> {
        match self.marks.pop() {
            Some(m) if m <= self.stack.len() => {
                let sizes = self.sizes.split_off(m);
                Ok((self.stack.split_off(m), Size::holding(&sizes)))
            }
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

    /// Grows the size of the top of the stack by values of `added` (a
    /// [`Size::holding`] them), refusing a value nested too deeply.
    fn grow_top(&mut self, at: usize, added: Size) -> Result<(), PickleError> {
        let Some(size) = self.sizes.last().copied() else {
            return self.fail(at, "stack underflow");
        };
        let size = size.adding(added);
        if size.depth > MAX_DEPTH {
            return self.fail(at, format!("values nested deeper than {MAX_DEPTH} levels"));
        }
        *self.sizes.last_mut().expect("checked") = size;
        Ok(())
    }

    /// Counts a copy of a value of `size` into or out of the memo, refusing
    /// one past the limit.
    fn copy(&mut self, at: usize, size: Size) -> Result<(), PickleError> {
        self.copied = self.copied.saturating_add(size.bytes);
        if self.copied > self.copy_limit {
            return self.fail(
                at,
                format!(
                    "the memo copies more than {} bytes of values",
                    self.copy_limit
                ),
            );
        }
        Ok(())
    }

    /// Stores a copy of the top of the stack in the memo at `i`.
    fn memo_put(&mut self, at: usize, i: u32) -> Result<(), PickleError> {
        let Some(size) = self.sizes.last().copied() else {
            return self.fail(at, "stack underflow");
        };
        self.copy(at, size)?;
        let v = self.top(at)?.clone();
        self.memo.insert(i, (v, size));
        Ok(())
    }

    fn push_items(&mut self, at: usize, items: Vec<Value>, size: Size) -> Result<(), PickleError> {
        match self.top(at)? {
            Value::List(_) => {}
            _ => return self.fail(at, "APPEND to a non-list"),
        }
        self.grow_top(at, size)?;
        if let Value::List(list) = self.top(at)? {
            list.extend(items);
        }
        Ok(())
    }

    fn set_items(&mut self, at: usize, items: Vec<Value>, size: Size) -> Result<(), PickleError> {
        if !items.len().is_multiple_of(2) {
            return self.fail(at, "odd number of dict items");
        }
        let added = match self.top(at)? {
            Value::Dict(_) => size,
            // The items go in a dict among the call's arguments, a level down.
            Value::Call(..) => Size::holding(&[size]),
            _ => return self.fail(at, "SETITEM on a non-dict"),
        };
        self.grow_top(at, added)?;
        let mut it = items.into_iter();
        let mut pairs = Vec::new();
        while let (Some(k), Some(v)) = (it.next(), it.next()) {
            pairs.push((k, v));
        }
        if let Value::Dict(dict) = self.top(at)? {
            dict.extend(pairs);
        } else if let Value::Call(_, args) = self.top(at)? {
            // A dict subclass made by a call (OrderedDict): record the items as
            // the call's state, which is what restoring it would do.
            match args.last_mut() {
                Some(Value::Dict(d)) => d.extend(pairs),
                _ => args.push(Value::Dict(pairs)),
            }
        }
        Ok(())
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
                    let (v, _) = self.pop(at)?;
                    return Ok((v, self.pos));
                }
                b'(' => self.marks.push(self.stack.len()),
                b'N' => self.push_leaf(at, Value::None)?,
                0x88 => self.push_leaf(at, Value::Bool(true))?,
                0x89 => self.push_leaf(at, Value::Bool(false))?,
                b'J' => {
                    let v = i32::from_le_bytes(self.le()?);
                    self.push_leaf(at, Value::Int(v as i64))?;
                }
                b'K' => {
                    let v = self.u8()?;
                    self.push_leaf(at, Value::Int(v as i64))?;
                }
                b'M' => {
                    let v = u16::from_le_bytes(self.le()?);
                    self.push_leaf(at, Value::Int(v as i64))?;
                }
                0x8a => {
                    // LONG1: little-endian two's complement of n bytes.
                    let n = self.u8()? as usize;
                    let bytes = self.take(n)?.to_vec();
                    if n > 8 {
                        // Only PyTorch's magic number is this long; keep its bytes.
                        self.push_leaf(at, Value::Bytes(bytes))?;
                    } else {
                        let mut buf = if bytes.last().is_some_and(|&b| b & 0x80 != 0) {
                            [0xff; 8]
                        } else {
                            [0; 8]
                        };
                        buf[..n].copy_from_slice(&bytes);
                        self.push_leaf(at, Value::Int(i64::from_le_bytes(buf)))?;
                    }
                }
                b'G' => {
                    let v = f64::from_be_bytes(self.le()?);
                    self.push_leaf(at, Value::Float(v))?;
                }
                b'X' => {
                    let n = u32::from_le_bytes(self.le()?) as usize;
                    let v = self.text(n)?;
                    self.push_leaf(at, v)?;
                }
                0x8c => {
                    let n = self.u8()? as usize;
                    let v = self.text(n)?;
                    self.push_leaf(at, v)?;
                }
                b'U' | b'C' => {
                    let n = self.u8()? as usize;
                    let v = self.take(n)?.to_vec();
                    self.push_leaf(at, Value::Bytes(v))?;
                }
                b'T' => {
                    let n = u32::from_le_bytes(self.le()?) as usize;
                    let v = self.take(n)?.to_vec();
                    self.push_leaf(at, Value::Bytes(v))?;
                }
                b')' => self.push_leaf(at, Value::Tuple(Vec::new()))?,
                b']' => self.push_leaf(at, Value::List(Vec::new()))?,
                b'}' => self.push_leaf(at, Value::Dict(Vec::new()))?,
                b't' => {
                    let (items, size) = self.pop_mark(at)?;
                    self.push(at, Value::Tuple(items), size)?;
                }
                b'l' => {
                    let (items, size) = self.pop_mark(at)?;
                    self.push(at, Value::List(items), size)?;
                }
                b'd' => {
                    let (items, size) = self.pop_mark(at)?;
                    self.push_leaf(at, Value::Dict(Vec::new()))?;
                    self.set_items(at, items, size)?;
                }
                0x85..=0x87 => {
                    let n = (op - 0x84) as usize;
                    if self.stack.len() < n {
                        return self.fail(at, "stack underflow");
                    }
                    let sizes = self.sizes.split_off(self.sizes.len() - n);
                    let items = self.stack.split_off(self.stack.len() - n);
                    self.push(at, Value::Tuple(items), Size::holding(&sizes))?;
                }
                b'a' => {
                    let (v, size) = self.pop(at)?;
                    self.push_items(at, vec![v], Size::holding(&[size]))?;
                }
                b'e' => {
                    let (items, size) = self.pop_mark(at)?;
                    self.push_items(at, items, size)?;
                }
                b's' => {
                    let (v, v_size) = self.pop(at)?;
                    let (k, k_size) = self.pop(at)?;
                    self.set_items(at, vec![k, v], Size::holding(&[k_size, v_size]))?;
                }
                b'u' => {
                    let (items, size) = self.pop_mark(at)?;
                    self.set_items(at, items, size)?;
                }
                b'c' => {
                    let module = self.line()?;
                    let name = self.line()?;
                    self.push_leaf(at, Value::Global(module, name))?;
                }
                0x93 => {
                    let (name, _) = self.pop(at)?;
                    let (module, _) = self.pop(at)?;
                    match (module, name) {
                        (Value::Str(m), Value::Str(n)) => {
                            self.push_leaf(at, Value::Global(m, n))?;
                        }
                        _ => return self.fail(at, "STACK_GLOBAL needs two strings"),
                    }
                }
                b'R' | 0x81 => {
                    let (args, args_size) = self.pop(at)?;
                    let (callable, callable_size) = self.pop(at)?;
                    let Value::Tuple(args) = args else {
                        return self.fail(at, "call arguments are not a tuple");
                    };
                    let size = Size::holding(&[callable_size, args_size]);
                    self.push(at, Value::Call(Box::new(callable), args), size)?;
                }
                b'b' => {
                    let (state, state_size) = self.pop(at)?;
                    let (obj, obj_size) = self.pop(at)?;
                    let size = Size::holding(&[obj_size, state_size]);
                    self.push(at, Value::Build(Box::new(obj), Box::new(state)), size)?;
                }
                b'Q' => {
                    let (id, size) = self.pop(at)?;
                    self.push(at, Value::Persistent(Box::new(id)), Size::holding(&[size]))?;
                }
                b'q' => {
                    let i = self.u8()? as u32;
                    self.memo_put(at, i)?;
                }
                b'r' => {
                    let i = u32::from_le_bytes(self.le()?);
                    self.memo_put(at, i)?;
                }
                0x94 => {
                    let i = self.memo.len() as u32;
                    self.memo_put(at, i)?;
                }
                b'h' | b'j' => {
                    let i = if op == b'h' {
                        self.u8()? as u32
                    } else {
                        u32::from_le_bytes(self.le()?)
                    };
                    let Some(size) = self.memo.get(&i).map(|(_, size)| *size) else {
                        return self.fail(at, format!("memo {i} is empty"));
                    };
                    self.copy(at, size)?;
                    let v = self.memo[&i].0.clone();
                    self.push(at, v, size)?;
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

    /// Pickles found by the property tests: values nested a level a byte
    /// (dropping them overflowed the stack), and a value doubled through
    /// the memo at each step (it filled the memory).
    #[test]
    fn deep_and_doubling_pickles_are_errors() {
        let mut deep = vec![b'N'];
        deep.extend(std::iter::repeat_n(0x85, 100_000));
        deep.push(b'.');
        let err = read_pickle(&deep).unwrap_err();
        assert_eq!(err.offset, MAX_DEPTH);
        assert!(err.message.contains("nested deeper"), "{err}");
        let mut at_limit = vec![b'N'];
        at_limit.extend(std::iter::repeat_n(0x85, MAX_DEPTH - 1));
        at_limit.push(b'.');
        let (value, _) = read_pickle(&at_limit).unwrap();
        assert!(!format!("{value:?}").is_empty());

        let mut doubling = vec![b'X', 1, 0, 0, 0, b'a', b'q', 0];
        for _ in 0..64 {
            doubling.extend([b'h', 0, b'h', 0, 0x86, b'q', 0]);
        }
        doubling.push(b'.');
        let err = read_pickle(&doubling).unwrap_err();
        assert!(err.message.contains("the memo copies more than"), "{err}");
    }
}
