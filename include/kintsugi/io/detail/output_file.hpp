// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file output_file.hpp
/// @brief An output file that appears only when complete: data goes to a temporary file
/// in the target directory, which is renamed over the target on commit(). If anything
/// fails before, the temporary file is removed and the target is left as it was.

#include <kintsugi/core/error.hpp>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace kintsugi::detail::io {

class AtomicOutputFile {
public:
    /// Creates the temporary file next to `target`; throws io_error when the directory
    /// does not exist or is not writable, or when `target` is a directory.
    explicit AtomicOutputFile(const std::filesystem::path& target) : target_(target), name_(target.string()) {
        std::error_code ec;
        if (target.filename().empty()) throw io_error(name_, "not a file name");
        if (std::filesystem::is_directory(target, ec)) throw io_error(name_, "is a directory, cannot write a file there");
        std::filesystem::path dir = target.parent_path();
        if (dir.empty()) dir = ".";
        if (!std::filesystem::is_directory(dir, ec))
            throw io_error(name_, "cannot write: directory '" + dir.string() + "' does not exist");
        std::random_device rd;
        for (int attempt = 0; attempt < 16 && !file_; ++attempt) {
            char suffix[24];
            std::snprintf(suffix, sizeof suffix, ".%08x.tmp", static_cast<unsigned>(rd()));
            tmp_ = dir / ("." + target.filename().string() + suffix);
            errno = 0;
            file_ = std::fopen(tmp_.string().c_str(), "wbx");
            if (!file_ && errno != EEXIST) break;
        }
        if (!file_)
            throw io_error(name_, "cannot create a temporary file in '" + dir.string() +
                                      "': " + std::generic_category().message(errno));
        buf_.resize(kBufferSize);
    }

    AtomicOutputFile(const AtomicOutputFile&) = delete;
    AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

    ~AtomicOutputFile() { discard(); }

    /// Returns a pointer to `n` writable bytes in the buffer (n <= 4096).
    char* reserve(std::size_t n) {
        if (pos_ + n > buf_.size()) flush_buffer();
        char* p = buf_.data() + pos_;
        pos_ += n;
        return p;
    }
    void write(const char* p, std::size_t n) {
        while (n > 0) {
            if (pos_ == buf_.size()) flush_buffer();
            const std::size_t k = std::min(n, buf_.size() - pos_);
            std::memcpy(buf_.data() + pos_, p, k);
            pos_ += k;
            p += k;
            n -= k;
        }
    }
    void write(std::string_view s) { write(s.data(), s.size()); }
    void put(char c) { *reserve(1) = c; }

    /// A double in the shortest text that reads back to the same value.
    void put_double(double v) {
        char* p = reserve(32);
        const auto r = std::to_chars(p, p + 32, v);
        pos_ -= static_cast<std::size_t>(p + 32 - r.ptr);
    }
    void put_uint(std::uint64_t v) {
        char* p = reserve(24);
        const auto r = std::to_chars(p, p + 24, v);
        pos_ -= static_cast<std::size_t>(p + 24 - r.ptr);
    }
    /// A binary value in the file's byte order (`swap` = differs from the machine's).
    template <class T>
    void put_binary(T v, bool swap) {
        char* p = reserve(sizeof(T));
        std::memcpy(p, &v, sizeof(T));
        if (swap) std::reverse(p, p + sizeof(T));
    }

    /// Flushes, closes and renames the temporary file over the target.
    void commit() {
        flush_buffer();
        std::FILE* f = file_;
        file_ = nullptr;
        if (std::fflush(f) != 0) {
            const int err = errno;
            std::fclose(f);
            remove_tmp();
            throw io_error(name_, "write error: " + std::generic_category().message(err));
        }
        if (std::fclose(f) != 0) {
            const int err = errno;
            remove_tmp();
            throw io_error(name_, "write error on close: " + std::generic_category().message(err));
        }
        std::error_code ec;
        std::filesystem::rename(tmp_, target_, ec);
        if (ec) {
            remove_tmp();
            throw io_error(name_, "cannot rename the temporary file into place: " + ec.message());
        }
        committed_ = true;
    }

    /// Path of the temporary file (for tests).
    [[nodiscard]] const std::filesystem::path& temporary_path() const { return tmp_; }

private:
    static constexpr std::size_t kBufferSize = std::size_t{1} << 20;

    void flush_buffer() {
        if (pos_ == 0) return;
        if (!file_) throw io_error(name_, "write after close");
        if (std::fwrite(buf_.data(), 1, pos_, file_) != pos_) {
            const int err = errno;
            std::fclose(file_);
            file_ = nullptr;
            remove_tmp();
            throw io_error(name_, "write error: " + std::generic_category().message(err));
        }
        pos_ = 0;
    }
    void remove_tmp() {
        std::error_code ec;
        std::filesystem::remove(tmp_, ec);
    }
    void discard() noexcept {
        if (committed_) return;
        if (file_) {
            std::fclose(file_);
            file_ = nullptr;
        }
        remove_tmp();
    }

    std::filesystem::path target_;
    std::string name_;
    std::filesystem::path tmp_;
    std::FILE* file_ = nullptr;
    std::vector<char> buf_;
    std::size_t pos_ = 0;
    bool committed_ = false;
};

}  // namespace kintsugi::detail::io
