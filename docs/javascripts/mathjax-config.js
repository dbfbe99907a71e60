// MathJax 3 for pymdownx.arithmatex (generic mode): \( \) inline, \[ \] display; the SVG output
// needs no font files. Material's instant navigation is off, so each page load typesets once.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"]],
    displayMath: [["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true
  },
  options: {
    ignoreHtmlClass: ".*|",
    processHtmlClass: "arithmatex"
  },
  startup: {
    pageReady: () => MathJax.startup.defaultPageReady().then(() => {
      document.documentElement.setAttribute("data-mathjax", "typeset");
    })
  }
};
