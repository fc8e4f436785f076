// Measured in a report page (test_certificate_lookover.py): overflowing cells and tables,
// numbers whose glyphs lie on more than one line.
(() => {
  const overflow = [], broken = [];
  const page = document.documentElement.clientWidth;
  for (const c of document.querySelectorAll("td, th")) {
    if (c.scrollWidth > c.clientWidth + 1) overflow.push("cell: " + c.textContent.trim().slice(0, 60));
  }
  for (const t of document.querySelectorAll("table")) {
    const r = t.getBoundingClientRect();
    if (r.right > page + 1) overflow.push(`table ${Math.round(r.right)} px > ${page} px: ` + t.textContent.trim().slice(0, 60));
  }
  // a number: digits with an optional sign, decimals and exponent, not inside a word (SHA-256)
  const NUM = /(?<![\w.])[−\-+]?\d[\d.,]*(?:[eE][−\-+]?\d+)?/g;
  const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
  for (let node; (node = walker.nextNode());) {
    const parent = node.parentElement;
    if (!parent || parent.closest("svg, style, script, details:not([open])")) continue;
    for (const m of node.data.matchAll(NUM)) {
      if (m[0].length < 2) continue;
      const r = document.createRange();
      r.setStart(node, m.index); r.setEnd(node, m.index + m[0].length);
      const lines = new Set([...r.getClientRects()].filter((x) => x.width > 0).map((x) => Math.round(x.top)));
      if (lines.size > 1) broken.push(`${m[0]} in «${node.data.trim().slice(0, 60)}»`);
    }
  }
  return { overflow, broken };
})
