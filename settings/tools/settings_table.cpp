// Writes the settings table (settings_table(), from setting_list.hpp) into a
// Markdown page between its markers, "<!-- settings table: generated ... -->"
// and "<!-- end of settings table -->"; without a page, prints it.
//   exodaq_settings_table [docs/operations.md]
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "exodaq/settings/setting_classes.hpp"

int main(int argc, char** argv) {
  const std::string table = exodaq::settings::settings_table();
  if (argc < 2) {
    std::cout << table;
    return 0;
  }
  std::ifstream in(argv[1]);
  std::stringstream page;
  page << in.rdbuf();
  std::string text = page.str();
  const auto from = text.find("<!-- settings table: generated");
  const auto to = text.find("<!-- end of settings table -->");
  if (!in || from == std::string::npos || to == std::string::npos || to < from) {
    std::cerr << "exodaq_settings_table: " << argv[1] << " has no settings table markers\n";
    return 1;
  }
  const auto table_from = text.find('\n', from) + 1;
  text.replace(table_from, to - table_from, table);
  std::ofstream(argv[1]) << text;
  return 0;
}
