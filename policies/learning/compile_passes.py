"""Graph pass for the compiled SAC updates (``rodlab train --compile``; docs/training.md, "Compiled updates").

Inductor on the CPU keeps every matrix product of the traced update a library call (oneDNN/MKL) and fuses only
the elementwise work around it. Products with a unit dimension, which the SAC networks have at each critic's output
layer (256 -> 1) and in its backward pass, cost more as library calls than as fused loops: ``x @ w`` with one output
column is a row-wise dot product (``(x * w^T).sum(1)``), the input gradient ``g @ w`` through that layer an outer
product (``g * w``), the weight gradient ``g^T @ x`` a column sum (``(g^T * x).sum(0)``). A library call for these
runs at a fraction of its rate and allocates its output; as loops they fuse with their neighbours.

``UnitProductLoops`` (part of ``--compile``) rewrites them and keeps the library's precision: the loops multiply and
sum in float32 and round once to bfloat16, after the bias (the output layer's ``addmm`` becomes one dot-plus-bias
loop), as the library's bfloat16 product does. It acts where a product computes in bfloat16 (or float16) on the
CPU, as in bfloat16 training (``--precision bfloat16``); float32 products and everything else are left to inductor.
"""
from __future__ import annotations

from collections import Counter

import torch
from torch._inductor.custom_graph_pass import CustomGraphPass, get_hash_for_files

aten = torch.ops.aten


def _meta(node):
    return node.meta.get("val") if isinstance(node, torch.fx.Node) else node


def _rewritable(*nodes) -> bool:
    """Tensors on the CPU in a 16-bit float type (float32 products are left to the library)."""
    vals = [_meta(n) for n in nodes]
    return all(isinstance(v, torch.Tensor) and v.device.type == "cpu" and v.dtype in (torch.bfloat16, torch.float16)
               for v in vals)


class UnitProductLoops(CustomGraphPass):
    """Post-grad pass: bfloat16 products with a unit dimension -> float32 loops rounded once (``addmm`` with one
    output column -> a dot product plus the bias). ``rewritten`` counts the nodes replaced by the last call
    (``dot_bias``, ``dot_rows``, ``outer``, ``sum_rows``)."""

    def __init__(self) -> None:
        self.rewritten: Counter = Counter()

    def uuid(self):
        # inductor's cache keys the compiled graph on this: one key per version of this file
        return get_hash_for_files((__file__,)) + type(self).__name__.encode()

    def __call__(self, graph: torch.fx.Graph) -> None:
        self.rewritten = Counter()
        f = _to_float32(graph)
        for node, bias, x, w in _biased_products(graph):
            if _meta(w).shape[1] != 1:
                continue
            with graph.inserting_before(node):
                dots = _dot_rows(graph, x, w, f)
                out = _cast(graph, _op(graph, aten.add.Tensor, dots, _cast(graph, bias, torch.float32)),
                            _meta(node).dtype)
            _replace(graph, node, out, "dot_bias", self.rewritten)
        # each 16-bit ``mm`` with a unit dimension -> a product and a sum, multiplied and summed in float32 and
        # rounded once (an outer product has no sum: it is one rounding either way)
        for node, a, b, (m, k, n) in _products(graph):
            with graph.inserting_before(node):
                if n == 1:  # (m, k) @ (k, 1): one dot product per row
                    out, kind = _dot_rows(graph, a, b, f), "dot_rows"
                elif k == 1:  # (m, 1) @ (1, n): an outer product
                    out, kind = _op(graph, aten.mul.Tensor, a, b), "outer"
                elif m == 1:  # (1, k) @ (k, n): a weighted sum of the rows of b
                    cols = _op(graph, aten.mul.Tensor, f(_op(graph, aten.permute.default, a, [1, 0])), f(b))
                    out, kind = _op(graph, aten.sum.dim_IntList, cols, [0], True), "sum_rows"
                else:
                    continue
                if kind != "outer":
                    out = _cast(graph, out, _meta(node).dtype)
            _replace(graph, node, out, kind, self.rewritten)


def _biased_products(graph: torch.fx.Graph):
    """(node, bias, x, w) of each plain ``addmm`` computing in a 16-bit float type on the CPU."""
    for node in list(graph.find_nodes(op="call_function", target=aten.addmm.default)):
        bias, x, w = node.args[:3]
        if node.kwargs.get("beta", 1) == 1 and node.kwargs.get("alpha", 1) == 1 and _rewritable(node, x, w):
            yield node, bias, x, w


def _products(graph: torch.fx.Graph):
    """(node, a, b, (m, k, n)) of each ``mm`` computing in a 16-bit float type on the CPU."""
    for node in list(graph.find_nodes(op="call_function", target=aten.mm.default)):
        a, b = node.args
        if _rewritable(node, a, b):
            yield node, a, b, (*_meta(a).shape, _meta(b).shape[1])


def _dot_rows(graph: torch.fx.Graph, x, w, f):
    """``(f(x) * f(w^T)).sum(1, keepdim)`` for a (k, 1) ``w``; ``f`` casts the factors (or leaves them)."""
    wt = f(_op(graph, aten.permute.default, w, [1, 0]))
    rows = _op(graph, aten.mul.Tensor, f(x), wt)
    return _op(graph, aten.sum.dim_IntList, rows, [1], True)


def _to_float32(graph: torch.fx.Graph):
    return lambda x: _cast(graph, x, torch.float32)


def _cast(graph: torch.fx.Graph, x, dtype: torch.dtype):
    return _op(graph, torch.ops.prims.convert_element_type.default, x, dtype)


def _op(graph: torch.fx.Graph, target, *args):
    """A new node ``target(*args)`` with its fake value (shape, dtype, device) computed as inductor expects."""
    node = graph.call_function(target, args)
    vals = [_meta(a) for a in args]
    fake_mode = next(v.fake_mode for v in vals if isinstance(v, torch.Tensor))
    with fake_mode:
        node.meta["val"] = target(*vals)
    return node


def _replace(graph: torch.fx.Graph, old: torch.fx.Node, new: torch.fx.Node, kind: str, counts: Counter) -> None:
    """``new`` in place of ``old`` when shape and dtype agree (else the new nodes are dropped again)."""
    was, now = _meta(old), _meta(new)
    if tuple(was.shape) != tuple(now.shape) or was.dtype != now.dtype:  # e.g. a bias of another dtype
        _drop_unused(graph, new)
        return
    old.replace_all_uses_with(new)
    graph.erase_node(old)
    counts[kind] += 1


def _drop_unused(graph: torch.fx.Graph, node: torch.fx.Node) -> None:
    """Erase ``node`` and the new nodes feeding only it (a rewrite that was not taken)."""
    todo = [node]
    while todo:
        n = todo.pop()
        if n.users or n.op != "call_function":
            continue
        inputs = [a for a in n.args if isinstance(a, torch.fx.Node)]
        graph.erase_node(n)
        todo.extend(inputs)


__all__ = ["UnitProductLoops"]
