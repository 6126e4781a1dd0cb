//! The syntax tree of a `.cso` file: what the text says, with a span on every node.
//!
//! The tree is deliberately close to the grammar; meaning (which fields a block
//! needs, what a name refers to, units) is the checker's job.

use std::fmt;

/// A byte range in one source text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Span {
    pub start: usize,
    pub end: usize,
}

impl Span {
    pub fn new(start: usize, end: usize) -> Self {
        Span { start, end }
    }

    /// The smallest span that covers both.
    pub fn to(self, other: Span) -> Span {
        Span::new(self.start.min(other.start), self.end.max(other.end))
    }

    pub fn len(&self) -> usize {
        self.end - self.start
    }

    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// A name as written, with its span.
#[derive(Debug, Clone, PartialEq)]
pub struct Ident {
    pub name: String,
    pub span: Span,
}

/// A whole file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct File {
    pub items: Vec<Item>,
    /// Keyword and name of each item that failed to parse (`body punch {` with a
    /// syntax error inside): the checker does not call them unknown where used.
    pub broken: Vec<(String, Option<String>)>,
}

/// One top-level item.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    pub kind: ItemKind,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub enum ItemKind {
    /// `let NAME = EXPR`
    Let { name: Ident, value: Expr },
    /// `gravity = VEC`
    Gravity { value: Expr },
    /// `minimize EXPR`
    Minimize { expr: Expr },
    /// `subject to EXPR`
    SubjectTo { expr: Expr },
    /// `fix | displace | symmetry | traction | pressure SEL [ {fields} ] [= EXPR]`
    Condition {
        keyword: Ident,
        selection: Expr,
        fields: Option<Block>,
        value: Option<Expr>,
    },
    /// `KEYWORD [NAME] [[N]] { fields }`
    Block {
        keyword: Ident,
        name: Option<Ident>,
        size: Option<Expr>,
        body: Block,
    },
}

/// `{ field, ... }`
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    pub fields: Vec<Field>,
    pub span: Span,
}

/// `NAME = VALUE` or a bare `NAME`.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub name: Ident,
    pub value: Option<Value>,
    pub span: Span,
}

/// A field's value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Expr(Expr),
    /// `a .. b`
    Range(Expr, Expr),
    /// `16 x 16`: each entry a number or a name.
    Grid(Vec<Expr>),
}

impl Value {
    pub fn span(&self) -> Span {
        match self {
            Value::Expr(e) => e.span,
            Value::Range(a, b) => a.span.to(b.span),
            Value::Grid(g) => match (g.first(), g.last()) {
                (Some(a), Some(b)) => a.span.to(b.span),
                _ => Span::default(),
            },
        }
    }
}

/// An expression with its span.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub enum ExprKind {
    /// A number, with the unit written after it if any.
    Number {
        value: f64,
        unit: Option<UnitExpr>,
    },
    Str(String),
    Name(String),
    Unary(UnOp, Box<Expr>),
    Binary(BinOp, Box<Expr>, Box<Expr>),
    /// `f(args)`
    Call {
        func: Box<Expr>,
        args: Vec<Expr>,
    },
    /// `base.name`
    Member {
        base: Box<Expr>,
        name: Ident,
    },
    /// `base[index]`
    Index {
        base: Box<Expr>,
        index: Box<Expr>,
    },
    /// `(a, b)` / `(a, b, c)`
    Vector(Vec<Expr>),
    /// `[a, b, c]`
    List(Vec<Expr>),
}

/// A unit as written: `kN/m` is `[(kN, 1), (m, -1)]`.
#[derive(Debug, Clone, PartialEq)]
pub struct UnitExpr {
    pub factors: Vec<(String, i32)>,
    pub span: Span,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnOp {
    Neg,
    Not,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
    And,
    Or,
}

impl BinOp {
    pub fn is_comparison(self) -> bool {
        matches!(
            self,
            BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne
        )
    }

    pub fn is_logical(self) -> bool {
        matches!(self, BinOp::And | BinOp::Or)
    }
}

impl fmt::Display for BinOp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Pow => "^",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
            BinOp::And => "&&",
            BinOp::Or => "||",
        };
        f.write_str(s)
    }
}
