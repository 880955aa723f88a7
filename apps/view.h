// `mbdae view RESULTS.h5 [-o FILE.html]`: one self-contained HTML file that plays the
// run in a browser (three.js inlined; docs/viewer.md).
#pragma once

#include <stdexcept>
#include <string>

namespace mbdae::app {

struct ViewOptions {
  std::string results;  // the results file
  std::string output;   // the HTML file; "" -> RESULTS with .html instead of .h5
  // three.min.js to inline; "" -> $MBDAE_THREE_JS, else the file of Debian's libjs-three
  // found when the program was built.
  std::string three_js;
  // At most this many rows are drawn and plotted (every k-th row and the last); a screen
  // cannot show more, and the page stays smooth.
  int max_frames = 2000;
};

// Bad command line or input (exit 2), e.g. a file that is not a results file.
class ViewInputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The page for a results file. Throws ViewInputError (not a results file, unreadable) or
// std::runtime_error (three.js missing).
std::string ViewerHtml(const ViewOptions& options);

// The command: argv[1] is "view". Returns the exit code (0, 2 bad input, 1 other).
int RunView(int argc, char** argv);

}  // namespace mbdae::app
