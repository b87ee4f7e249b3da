#!/usr/bin/env python3
"""Counts the public items reachable from a crate's root in rustdoc's JSON output.

Usage: count_public_api.py DOC.json [--trait-items]

DOC.json is what `cargo rustdoc -p snowpack --lib -- -Z unstable-options
--output-format json` writes (RUSTC_BOOTSTRAP=1 on a stable toolchain). Items
are followed from the root: module items, re-exports (a glob re-export of a
module counts its items), struct fields, enum variants and their fields,
inherent impl items and trait items; trait impls only with --trait-items.
An item reached twice is counted once.
"""
import json, sys, collections
doc = json.load(open(sys.argv[1]))
index = doc["index"]
root = str(doc["root"])
seen = set()
kinds = collections.Counter()
root_names = []
stack = [root]
def kind_of(item):
    return next(iter(item["inner"])) if isinstance(item["inner"], dict) else item["inner"]
def push(i):
    if i is not None and str(i) in index and str(i) not in seen:
        stack.append(str(i))
while stack:
    i = stack.pop()
    if i in seen: continue
    seen.add(i)
    item = index[i]
    k = kind_of(item)
    inner = item["inner"][k] if isinstance(item["inner"], dict) else None
    if k == "use":
        tgt = inner.get("id")
        if tgt is not None and str(tgt) in index:
            t = index[str(tgt)]
            if inner.get("is_glob") and kind_of(t) == "module":
                for c in t["inner"]["module"]["items"]: push(c)
            else:
                push(tgt)
        continue
    if k == "impl":
        if inner.get("trait") is None or "--trait-items" in sys.argv:
            for c in inner["items"]: push(c)
        continue
    # "default" is the visibility of enum variants and trait items.
    if item.get("visibility") not in ("public", "default"):
        continue
    kinds[k] += 1
    if k == "module":
        for c in inner["items"]: push(c)
    elif k == "struct":
        sk = inner["kind"]
        if isinstance(sk, dict):
            if "plain" in sk:
                for f in sk["plain"]["fields"]: push(f)
            elif "tuple" in sk:
                for f in sk["tuple"]:
                    push(f)
        for c in inner.get("impls", []): push(c)
    elif k == "enum":
        for v in inner["variants"]: push(v)
        for c in inner.get("impls", []): push(c)
    elif k == "variant":
        vk = inner["kind"]
        if isinstance(vk, dict):
            if "struct" in vk:
                for f in vk["struct"]["fields"]: push(f)
            elif "tuple" in vk:
                for f in vk["tuple"]: push(f)
    elif k == "union":
        for f in inner.get("fields", []): push(f)
        for c in inner.get("impls", []): push(c)
    elif k == "trait":
        for c in inner["items"]: push(c)
        for c in inner.get("implementations", []): push(c)
total = sum(kinds.values())
print(f"public items reachable from the root: {total}")
for k, n in kinds.most_common():
    print(f"  {k}: {n}")
