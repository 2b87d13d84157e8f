"""Shader maths written as Python expressions: each operation adds a Math or
Vector Math node to a node tree (Cycles and EEVEE both evaluate them).

    b = Builder(tree)
    d = b.normalize(b.input_vector("plod_view", (0, 0, 1)))
    mu = b.dot(d, up)
    colour = b.vexp(-tau * mu)          # vector * scalar -> Vector Math
"""


class Expr:
    __slots__ = ("b", "socket", "vector")

    def __init__(self, builder, socket, vector):
        self.b, self.socket, self.vector = builder, socket, vector

    def _op(self, other, op, swap=False):
        a, c = (other, self) if swap else (self, other)
        return self.b.binary(op, a, c)

    def __add__(self, o): return self._op(o, "ADD")
    def __radd__(self, o): return self._op(o, "ADD", True)
    def __sub__(self, o): return self._op(o, "SUBTRACT")
    def __rsub__(self, o): return self._op(o, "SUBTRACT", True)
    def __mul__(self, o): return self._op(o, "MULTIPLY")
    def __rmul__(self, o): return self._op(o, "MULTIPLY", True)
    def __truediv__(self, o): return self._op(o, "DIVIDE")
    def __rtruediv__(self, o): return self._op(o, "DIVIDE", True)
    def __neg__(self): return self.b.binary("MULTIPLY", self, -1.0)


class Builder:
    def __init__(self, tree, x0=-3000, y0=0):
        self.tree, self.nodes, self.links = tree, tree.nodes, tree.links
        self.count = 0
        self.x0, self.y0 = x0, y0

    def _place(self, node):
        node.location = (self.x0 + 160 * (self.count // 12), self.y0 - 90 * (self.count % 12))
        self.count += 1
        node.hide = True
        return node

    def node(self, kind):
        return self._place(self.nodes.new(kind))

    def link(self, value, socket):
        """Connects an Expr (or sets a constant) to an input socket."""
        if isinstance(value, Expr):
            self.links.new(value.socket, socket)
        elif isinstance(value, (tuple, list)):
            socket.default_value = tuple(value)[:len(socket.default_value)]
        else:
            socket.default_value = value if not hasattr(socket.default_value, "__len__") \
                else (value,) * len(socket.default_value)

    def const(self, value):
        if isinstance(value, (tuple, list)):
            node = self.node("ShaderNodeCombineXYZ")
            for i in range(3):
                node.inputs[i].default_value = value[i]
            return Expr(self, node.outputs[0], True)
        node = self.node("ShaderNodeValue")
        node.outputs[0].default_value = value
        return Expr(self, node.outputs[0], False)

    def input_vector(self, name, default=(0.0, 0.0, 0.0)):
        """A named Combine XYZ node whose three inputs a handler updates."""
        node = self.nodes.get(name) or self.node("ShaderNodeCombineXYZ")
        node.name = node.label = name
        for i in range(3):
            node.inputs[i].default_value = default[i]
        return Expr(self, node.outputs[0], True)

    def input_value(self, name, default=0.0):
        node = self.nodes.get(name) or self.node("ShaderNodeValue")
        node.name = node.label = name
        node.outputs[0].default_value = default
        return Expr(self, node.outputs[0], False)

    @staticmethod
    def _is_vector(v):
        return isinstance(v, (tuple, list)) or (isinstance(v, Expr) and v.vector)

    def binary(self, op, a, c):
        if self._is_vector(a) or self._is_vector(c):
            return self.vmath(op, a, c)
        return self.math(op, a, c)

    def math(self, op, a, c=None, d=None, clamp=False):
        node = self.node("ShaderNodeMath")
        node.operation = op
        node.use_clamp = clamp
        for i, v in enumerate((a, c, d)):
            if v is not None:
                self.link(v, node.inputs[i])
        return Expr(self, node.outputs[0], False)

    def vmath(self, op, a, c=None, d=None):
        node = self.node("ShaderNodeVectorMath")
        node.operation = op
        for i, v in enumerate((a, c, d)):
            if v is not None:
                if not self._is_vector(v) and not isinstance(v, Expr):
                    v = (v, v, v)
                if op == "SCALE" and i == 1:
                    self.link(v, node.inputs["Scale"])
                else:
                    self.link(v, node.inputs[i])
        scalar = op in ("DOT_PRODUCT", "LENGTH", "DISTANCE")
        return Expr(self, node.outputs["Value" if scalar else "Vector"], not scalar)

    # scalar helpers
    def exp(self, a): return self.math("EXPONENT", a)
    def sqrt(self, a): return self.math("SQRT", a)
    def maximum(self, a, c): return self.binary("MAXIMUM", a, c)
    def minimum(self, a, c): return self.binary("MINIMUM", a, c)
    def power(self, a, c): return self.math("POWER", a, c)
    def less(self, a, c): return self.math("LESS_THAN", a, c)
    def smoothstep(self, edge0, edge1, x):
        t = self.math("DIVIDE", x - edge0, edge1 - edge0)
        t = self.math("MINIMUM", self.math("MAXIMUM", t, 0.0), 1.0)
        return t * t * (3.0 - 2.0 * t)

    def mix(self, a, c, t):
        return a + (c - a) * t

    # vector helpers
    def dot(self, a, c): return self.vmath("DOT_PRODUCT", a, c)
    def length(self, a): return self.vmath("LENGTH", a)
    def normalize(self, a): return self.vmath("NORMALIZE", a)
    def cross(self, a, c): return self.vmath("CROSS_PRODUCT", a, c)

    def split(self, v):
        node = self.node("ShaderNodeSeparateXYZ")
        self.link(v, node.inputs[0])
        return [Expr(self, node.outputs[i], False) for i in range(3)]

    def combine(self, x, y, z):
        node = self.node("ShaderNodeCombineXYZ")
        for i, v in enumerate((x, y, z)):
            self.link(v, node.inputs[i])
        return Expr(self, node.outputs[0], True)

    def vexp(self, v):
        return self.combine(*(self.exp(c) for c in self.split(v)))

    def socket(self, socket, vector=True):
        return Expr(self, socket, vector)
