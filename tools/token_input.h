// Where a tool that connects finds its connect token: never on the command line, where `ps`
// shows it to every user of the machine. --token-file FILE, else the file named by
// $PROBECAST_TOKEN_FILE, else the token itself in $PROBECAST_TOKEN.
#pragma once

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "common/result.h"
#include "protocol/connect_token.h"

namespace pc {

inline Result<std::string> readTokenFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{"token file " + path + ": cannot be read"};
  std::string text;
  text.resize(kMaxTokenChars + 2);
  in.read(text.data(), std::streamsize(text.size()));
  text.resize(std::size_t(in.gcount()));
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r' || text.back() == ' '))
    text.pop_back();
  if (text.size() > kMaxTokenChars)
    return Error{"token file " + path + ": longer than a token (" + std::to_string(kMaxTokenChars) +
                 " characters)"};
  if (text.empty()) return Error{"token file " + path + ": empty"};
  return text;
}

inline Result<std::string> connectToken(const std::string& tokenFile) {
  if (!tokenFile.empty()) return readTokenFile(tokenFile);
  if (const char* file = std::getenv("PROBECAST_TOKEN_FILE"); file && *file)
    return readTokenFile(file);
  if (const char* token = std::getenv("PROBECAST_TOKEN"); token && *token)
    return std::string(token);
  return Error{
      "no connect token: pass --token-file FILE, or set PROBECAST_TOKEN_FILE or PROBECAST_TOKEN "
      "(probecast-token issue makes one)"};
}

}  // namespace pc
