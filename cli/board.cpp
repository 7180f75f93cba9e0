// clearfit board: a printable AprilTag board (SVG at exact size) and its board file.
#include <clearfit/cli/commands.hpp>

#include <algorithm>
#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/board.hpp>
#include <clearfit/error.hpp>
#include <iostream>

namespace clearfit::cli {

Run add_board(CLI::App& app) {
  struct Opts {
    BoardLayout layout;
    std::string svg, board_file;
  };
  auto o = std::make_shared<Opts>();
  o->layout.rows = 6, o->layout.cols = 8, o->layout.tag_mm = 20, o->layout.gap_mm = 20;
  CLI::App* sub = app.add_subcommand(
      "board", "Write a printable AprilTag calibration board (SVG at exact size) and its board file");
  sub->add_option("--rows", o->layout.rows, "Tags down")->capture_default_str();
  sub->add_option("--cols", o->layout.cols, "Tags across")->capture_default_str();
  sub->add_option("--tag-mm", o->layout.tag_mm, "Edge of each tag's black square, mm")->capture_default_str();
  sub->add_option(
         "--gap-mm", o->layout.gap_mm,
         "White gap between black squares, mm (= --tag-mm puts every corner on one grid, as mrcal needs)")
      ->capture_default_str();
  sub->add_option("--family", o->layout.family, "AprilTag family")->capture_default_str();
  sub->add_option("--first-id", o->layout.first_id, "Id of the top-left tag")->capture_default_str();
  sub->add_option("--out", o->svg, "Printable board (.svg)");
  sub->add_option("--board-file", o->board_file,
                  "Board file (clearfit.board/1 YAML) for detect and calibrate");
  return [o]() {
    if (o->svg.empty() && o->board_file.empty())
      throw InputError("", "--out/--board-file", "nothing to write",
                       "give --out board.svg and/or --board-file board.yaml");
    if (!o->svg.empty() && std::filesystem::path(o->svg).extension() != ".svg")
      throw InputError(
          "", "--out", "'" + o->svg + "' is not an .svg file",
          "PDF is not built in: write .svg and print it at 100 %, or convert it (e.g. rsvg-convert -f pdf)");
    Board board;
    try {
      board = make_board(o->layout);
    } catch (const InputError& e) {  // name the option the user typed: gap_mm -> --gap-mm
      std::string option = e.element();
      option.insert(0, "--");
      std::replace(option.begin(), option.end(), '_', '-');
      throw InputError("", option, e.problem(), e.hint());
    }
    if (!o->svg.empty()) write_file_atomically(o->svg, board_svg(board));
    if (!o->board_file.empty()) write_board(board, o->board_file);
    std::cout << describe(board) << "\n";
    if (!o->svg.empty())
      std::cout << "printable board: " << o->svg
                << " (print at 100 %; check the scale bar and a black square with a ruler)\n";
    if (!o->board_file.empty()) std::cout << "board file: " << o->board_file << "\n";
    return 0;
  };
}

static const Registration registered{"board", 30, add_board};

}  // namespace clearfit::cli
