// Writing a file so that readers see either the old file or the whole new one, never a part: the bytes go
// to PATH.tmp, are flushed to the disk (fsync), then renamed over PATH. On any failure PATH is unchanged,
// PATH.tmp is removed and std::runtime_error names the file and the reason.
#pragma once

#include <string>
#include <string_view>

namespace hns::ppo {

void write_file_atomically(const std::string& path, std::string_view bytes);

}  // namespace hns::ppo
