// A small JSON reader for the test vectors (host tests only; uses the heap).
// Supports objects, arrays, strings without escapes beyond \" \\ \/ \n \t,
// numbers, true, false and null. Errors abort with a message.
#pragma once

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace json {

struct Value {
  enum Kind { kNull, kBool, kNumber, kString, kArray, kObject } kind = kNull;
  bool b = false;
  double num = 0.0;
  std::string str;
  std::vector<Value> arr;
  std::map<std::string, Value> obj;

  const Value& operator[](const char* key) const {
    auto it = obj.find(key);
    if (kind != kObject || it == obj.end()) {
      fprintf(stderr, "json: missing key %s\n", key);
      abort();
    }
    return it->second;
  }
  const Value& operator[](size_t i) const {
    if (kind != kArray || i >= arr.size()) {
      fprintf(stderr, "json: index %lu out of range\n", static_cast<unsigned long>(i));
      abort();
    }
    return arr[i];
  }
  bool has(const char* key) const { return kind == kObject && obj.count(key) != 0; }
  size_t size() const { return kind == kArray ? arr.size() : obj.size(); }
  double number() const { return num; }
  long long integer() const { return static_cast<long long>(num); }
};

class Parser {
 public:
  explicit Parser(const std::string& text) : s_(text) {}

  Value parse() {
    Value v = value();
    ws();
    if (i_ != s_.size()) die("trailing characters");
    return v;
  }

 private:
  [[noreturn]] void die(const char* what) {
    fprintf(stderr, "json: %s at offset %lu\n", what, static_cast<unsigned long>(i_));
    abort();
  }
  void ws() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\r' || s_[i_] == '\t')) ++i_;
  }
  char peek() {
    ws();
    if (i_ >= s_.size()) die("unexpected end");
    return s_[i_];
  }
  void expect(char c) {
    if (peek() != c) die("unexpected character");
    ++i_;
  }
  bool literal(const char* word) {
    const std::string w(word);
    if (s_.compare(i_, w.size(), w) == 0) {
      i_ += w.size();
      return true;
    }
    return false;
  }
  std::string string() {
    expect('"');
    std::string out;
    while (true) {
      if (i_ >= s_.size()) die("unterminated string");
      const char c = s_[i_++];
      if (c == '"') break;
      if (c == '\\') {
        if (i_ >= s_.size()) die("bad escape");
        const char e = s_[i_++];
        switch (e) {
          case '"': out += '"'; break;
          case '\\': out += '\\'; break;
          case '/': out += '/'; break;
          case 'n': out += '\n'; break;
          case 't': out += '\t'; break;
          default: die("unsupported escape");
        }
      } else {
        out += c;
      }
    }
    return out;
  }
  Value value() {
    Value v;
    const char c = peek();
    if (c == '{') {
      ++i_;
      v.kind = Value::kObject;
      if (peek() == '}') {
        ++i_;
        return v;
      }
      while (true) {
        std::string key = string();
        expect(':');
        v.obj[key] = value();
        if (peek() == ',') {
          ++i_;
          continue;
        }
        expect('}');
        return v;
      }
    }
    if (c == '[') {
      ++i_;
      v.kind = Value::kArray;
      if (peek() == ']') {
        ++i_;
        return v;
      }
      while (true) {
        v.arr.push_back(value());
        if (peek() == ',') {
          ++i_;
          continue;
        }
        expect(']');
        return v;
      }
    }
    if (c == '"') {
      v.kind = Value::kString;
      v.str = string();
      return v;
    }
    if (literal("true")) {
      v.kind = Value::kBool;
      v.b = true;
      return v;
    }
    if (literal("false")) {
      v.kind = Value::kBool;
      return v;
    }
    if (literal("null")) return v;
    const char* start = s_.c_str() + i_;
    char* end = nullptr;
    v.num = strtod(start, &end);
    if (end == start) die("bad value");
    v.kind = Value::kNumber;
    i_ += static_cast<size_t>(end - start);
    return v;
  }

  const std::string& s_;
  size_t i_ = 0;
};

inline bool read_file(const char* path, std::string* out) {
  FILE* f = fopen(path, "rb");
  if (f == nullptr) return false;
  char buf[65536];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, f)) > 0) out->append(buf, n);
  fclose(f);
  return true;
}

inline std::vector<uint8_t> unhex(const std::string& hex) {
  std::vector<uint8_t> out;
  auto nibble = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    fprintf(stderr, "json: bad hex digit %c\n", c);
    abort();
  };
  for (size_t i = 0; i + 1 < hex.size(); i += 2) {
    out.push_back(static_cast<uint8_t>(nibble(hex[i]) << 4 | nibble(hex[i + 1])));
  }
  return out;
}

}  // namespace json
