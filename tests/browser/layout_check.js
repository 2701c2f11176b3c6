// Appended to a truepos report by crates/cli/tests/report_browser.rs and run by headless
// Chromium: checks what only a browser with real fonts can tell — every figure renders with a
// size, and no two labels of a figure overlap (a legend over a label, a tick over a title).
// The verdict goes into a pre element (id layout-verdict) for --dump-dom.
(function () {
  const problems = [];
  const figures = document.querySelectorAll("figure svg");
  if (figures.length === 0) problems.push("no figure");
  figures.forEach((svg, f) => {
    const box = svg.getBoundingClientRect();
    const name = (svg.parentElement.querySelector("figcaption") || {}).textContent || `figure ${f}`;
    if (box.width < 100 || box.height < 100) problems.push(`${name}: rendered ${box.width}×${box.height}`);
    const texts = Array.from(svg.querySelectorAll("text"))
      .filter((t) => t.textContent.trim() !== "")
      .map((t) => ({ text: t.textContent.trim(), r: t.getBoundingClientRect() }));
    for (const t of texts) {
      if (t.r.left < box.left - 1 || t.r.right > box.right + 1 || t.r.top < box.top - 1 || t.r.bottom > box.bottom + 1)
        problems.push(`${name}: "${t.text}" leaves the figure`);
    }
    for (let i = 0; i < texts.length; i++)
      for (let j = i + 1; j < texts.length; j++) {
        const a = texts[i].r, b = texts[j].r;
        const w = Math.min(a.right, b.right) - Math.max(a.left, b.left);
        const h = Math.min(a.bottom, b.bottom) - Math.max(a.top, b.top);
        if (w > 1 && h > 1) problems.push(`${name}: "${texts[i].text}" overlaps "${texts[j].text}"`);
      }
  });
  const pre = document.createElement("pre");
  pre.id = "layout-verdict";
  pre.textContent = JSON.stringify({ figures: figures.length, problems });
  document.body.appendChild(pre);
})();
