# Writes OUT: a C++ file defining mbdae::app::kViewerHtml and kViewerJs, the text of
# HTML and JS (viewer/viewer.html, viewer/viewer.js), for `mbdae view`.
# cmake -DHTML=... -DJS=... -DOUT=... -P embed.cmake
file(READ "${HTML}" html)
file(READ "${JS}" js)
set(delim "MBDAEVIEW")
file(WRITE "${OUT}.tmp"
  "// Generated from viewer/viewer.html and viewer/viewer.js by viewer/embed.cmake.\n"
  "namespace mbdae::app {\n"
  "extern const char* const kViewerHtml;\n"
  "extern const char* const kViewerJs;\n"
  "const char* const kViewerHtml = R\"${delim}(${html})${delim}\";\n"
  "const char* const kViewerJs = R\"${delim}(${js})${delim}\";\n"
  "}  // namespace mbdae::app\n")
file(RENAME "${OUT}.tmp" "${OUT}")
