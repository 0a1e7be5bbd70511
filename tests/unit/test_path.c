/* The one containment check and the one mkdir -p (obscura/path.h): their edge cases. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "testutil.h"

static void test_inside_children_and_self(void **state) {
  (void)state;
  assert_true(obs_path_is_inside("/a/b", "/a/b/c.obj"));
  assert_true(obs_path_is_inside("/a/b", "/a/b/c/d/e.obj"));
  assert_true(obs_path_is_inside("/a/b", "/a/b")); /* the directory itself */
  assert_false(obs_path_is_inside("/a/b", "/a/c.obj"));
  assert_false(obs_path_is_inside("/a/b", "/a"));
  assert_false(obs_path_is_inside("/a/b/c", "/a/b"));
}

/* A sibling that shares the prefix is not a child, with or without trailing slashes. */
static void test_inside_prefix_is_not_child(void **state) {
  (void)state;
  assert_false(obs_path_is_inside("/a/b", "/a/bc"));
  assert_false(obs_path_is_inside("/a/b", "/a/bc/c.obj"));
  assert_false(obs_path_is_inside("/a/b/", "/a/bc/c.obj"));
  assert_false(obs_path_is_inside("/a/b", "/a/b.obj"));
  assert_false(obs_path_is_inside("/a/b", "/a/b-c/x"));
}

static void test_inside_trailing_slashes(void **state) {
  (void)state;
  assert_true(obs_path_is_inside("/a/b/", "/a/b/c.obj"));
  assert_true(obs_path_is_inside("/a/b//", "/a/b/c.obj"));
  assert_true(obs_path_is_inside("/a/b/", "/a/b"));
  assert_true(obs_path_is_inside("/a/b", "/a/b/"));
  assert_true(obs_path_is_inside("/a/b/", "/a/b/"));
}

static void test_inside_root(void **state) {
  (void)state;
  assert_true(obs_path_is_inside("/", "/"));
  assert_true(obs_path_is_inside("/", "/etc/passwd"));
  assert_true(obs_path_is_inside("//", "/etc"));
  assert_false(obs_path_is_inside("/", "etc/passwd")); /* not resolved: not absolute */
  assert_false(obs_path_is_inside("/etc", "/"));
}

static void test_inside_empty(void **state) {
  (void)state;
  assert_false(obs_path_is_inside("", "/a"));
  assert_false(obs_path_is_inside("/a", ""));
  assert_false(obs_path_is_inside(NULL, "/a"));
  assert_false(obs_path_is_inside("/a", NULL));
}

/* Lexical only: the caller resolves symlinks; with realpath a link out of the tree is caught. */
static void test_inside_symlink_resolved_by_caller(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("path_symlink");
  char tree[1024], outside[1024], link[1100], real_tree[4096], real_link[4096];
  snprintf(tree, sizeof tree, "%s/tree", dir);
  snprintf(outside, sizeof outside, "%s/outside", dir);
  snprintf(link, sizeof link, "%s/escape", tree);
  assert_int_equal(obs_path_make_dirs(tree, NULL), 0);
  assert_int_equal(obs_path_make_dirs(outside, NULL), 0);
  unlink(link);
  assert_int_equal(symlink(outside, link), 0);
  assert_true(obs_path_is_inside(tree, link)); /* as written it looks inside */
  assert_non_null(realpath(tree, real_tree));
  assert_non_null(realpath(link, real_link));
  assert_false(obs_path_is_inside(real_tree, real_link)); /* resolved, it is not */
}

static int is_dir(const char *p) {
  struct stat st;
  return !stat(p, &st) && S_ISDIR(st.st_mode);
}

static void test_make_dirs(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("path_mkdirs");
  char p[1024];
  obs_err err = OBS_ERR_INIT;
  snprintf(p, sizeof p, "%s/a/b/c", dir);
  assert_int_equal(obs_path_make_dirs(p, &err), 0);
  assert_true(is_dir(p));
  assert_int_equal(obs_path_make_dirs(p, &err), 0); /* existing: fine */
  snprintf(p, sizeof p, "%s/t/u//v/", dir);          /* doubled and trailing slashes */
  assert_int_equal(obs_path_make_dirs(p, &err), 0);
  snprintf(p, sizeof p, "%s/t/u/v", dir);
  assert_true(is_dir(p));
  assert_int_equal(obs_path_make_dirs("/", &err), 0);
  obs_err_free(&err);
}

static void test_make_dirs_refuses_files_and_empty(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("path_mkdirs_file");
  char f[1024], below[1100];
  snprintf(f, sizeof f, "%s/file", dir);
  FILE *fp = fopen(f, "w");
  assert_non_null(fp);
  fclose(fp);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_path_make_dirs(f, &err), OBS_EIO);
  assert_non_null(strstr(obs_err_message(&err), "exists and is not a directory"));
  assert_int_equal(errno, ENOTDIR);
  obs_err_free(&err);
  snprintf(below, sizeof below, "%s/x/y", f);
  assert_int_equal(obs_path_make_dirs(below, &err), OBS_EIO);
  assert_non_null(strstr(obs_err_message(&err), "cannot create directory"));
  assert_int_equal(errno, ENOTDIR); /* kept for the caller's explanation */
  obs_err_free(&err);
  assert_int_equal(obs_path_make_dirs("", &err), OBS_EINVAL);
  obs_err_free(&err);
  assert_int_equal(obs_path_make_dirs(NULL, NULL), OBS_EINVAL);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_inside_children_and_self),
      cmocka_unit_test(test_inside_prefix_is_not_child),
      cmocka_unit_test(test_inside_trailing_slashes),
      cmocka_unit_test(test_inside_root),
      cmocka_unit_test(test_inside_empty),
      cmocka_unit_test(test_inside_symlink_resolved_by_caller),
      cmocka_unit_test(test_make_dirs),
      cmocka_unit_test(test_make_dirs_refuses_files_and_empty),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
