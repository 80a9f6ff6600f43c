// JSON text of a value whose strings may come from outside: file names, ids, label headers,
// request bodies. nlohmann's dump() throws type_error 316 on bytes that are not UTF-8, far from
// the file or name that held them (and after an output folder was made); json_text() writes
// such bytes as U+FFFD instead. Every JSON the project writes goes through it.
#pragma once

#include <string>

namespace bodymodel {

template <class Json>
std::string json_text(const Json& j, int indent = -1) {
  return j.dump(indent, ' ', false, Json::error_handler_t::replace);
}

}  // namespace bodymodel
