// Where a tool that connects finds its connect token: never on the command line, where `ps`
// shows it to every user of the machine. --token-file FILE, else the file named by
// $PROBECAST_TOKEN_FILE, else the token itself in $PROBECAST_TOKEN.
#pragma once

#include <cstdlib>
#include <string>

#include "common/result.h"
#include "protocol/connect_token.h"
#include "protocol/secure_io.h"

namespace pc {

inline Result<std::string> readTokenFile(const std::string& path) {
  auto read = readSmallFile(path, kMaxTokenChars + 2);  // a token and its line end
  if (!read) return Error{"token file: " + read.error().message};
  std::string text = std::move(read).value();
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r' || text.back() == ' '))
    text.pop_back();
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
