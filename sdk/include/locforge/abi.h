/* locforge plugin ABI, version 1.
 *
 * This header is plain C on purpose: it is the only contract between the host
 * (`locforge`) and a plugin shared library, so plugins built by other people,
 * with other compilers or flags, keep working. sdk/PLUGIN_ABI.md gives the
 * compatibility rules in full. In short:
 *
 *  - A plugin exports exactly one symbol, `locforge_plugin_entry`, which
 *    returns a pointer to a static LfPluginInfo. The host checks
 *    `abi_version` and `struct_size` before it reads any other field, and
 *    refuses the library with a message if they do not match.
 *  - Every struct starts with `struct_size`. Fields are only ever appended;
 *    a reader uses a field only when `struct_size` says it is present.
 *    Removing or reordering fields bumps LF_ABI_VERSION.
 *  - No C++ exception, and no C++ type, crosses this boundary. Every call
 *    returns a status (0 = ok) and fills an LfError with a message.
 *  - All metadata (stages, parameters with types, defaults, ranges, docs,
 *    ports) is static data readable without creating a stage.
 *  - A plugin is never unloaded while the host runs.
 *  - A plugin must not change process-wide state (signal handlers, thread
 *    caps, locale, environment, current directory).
 */
#ifndef LOCFORGE_ABI_H_
#define LOCFORGE_ABI_H_

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define LF_ABI_VERSION 1u
#define LF_ENTRY_SYMBOL "locforge_plugin_entry"

#if defined(_WIN32)
#define LF_EXPORT __declspec(dllexport)
#else
#define LF_EXPORT __attribute__((visibility("default")))
#endif

/* Status codes returned by every plugin call. */
enum {
  LF_OK = 0,
  LF_ERROR = 1,        /* failed; LfError.message says why */
  LF_BAD_PARAMS = 2,   /* parameters refused; message names the parameter */
  LF_BAD_INPUT = 3,    /* input data refused; message names file/line/field */
  LF_CANCELLED = 4     /* the host asked to stop */
};

/* Error channel: the callee writes a NUL-terminated message. */
typedef struct LfError {
  uint32_t struct_size;
  char message[2048];
} LfError;

/* ---- Parameters ------------------------------------------------------- */

typedef enum LfParamType {
  LF_PARAM_BOOL = 0,
  LF_PARAM_INT = 1,          /* int64 */
  LF_PARAM_DOUBLE = 2,
  LF_PARAM_STRING = 3,
  LF_PARAM_PATH = 4,         /* a file or folder; part of the cache key by content stamp;
                                empty = none given, allowed unless LF_PARAM_REQUIRED */
  LF_PARAM_ENUM = 5,         /* one of `choices` */
  LF_PARAM_INT_LIST = 6,
  LF_PARAM_DOUBLE_LIST = 7,
  LF_PARAM_STRING_LIST = 8,
  LF_PARAM_COMPONENT = 9     /* an in-process component chosen in the graph: a stage id and the
                                parameters given to it (format below); the host checks them
                                against that stage's own declarations */
} LfParamType;

/* Flags of a parameter. */
enum {
  LF_PARAM_REQUIRED = 1u << 0,     /* no default; the graph must set it */
  LF_PARAM_NO_CACHE_KEY = 1u << 1, /* does not change results (e.g. verbosity) */
  LF_PARAM_DERIVED = 1u << 2       /* default_value "" (required so, and not LF_PARAM_REQUIRED):
                                      not given, the stage derives the value (e.g. from a preset
                                      the graph chose); "" is valid */
};

/* One declared parameter. Values cross the boundary as canonical strings:
 * bools "true"/"false", ints in decimal, doubles with 17 significant digits,
 * lists as their elements joined by LF_LIST_SEPARATOR. */
#define LF_LIST_SEPARATOR '\x1f'
/* LF_PARAM_COMPONENT values: "kind/name", then for each parameter given to the
 * component, in name order, LF_COMPONENT_SEPARATOR "name=value" with the
 * value in its canonical form (lists keep LF_LIST_SEPARATOR). */
#define LF_COMPONENT_SEPARATOR '\x1e'

typedef struct LfParamSpec {
  uint32_t struct_size;
  const char* name;          /* YAML key, snake_case */
  uint32_t type;             /* LfParamType */
  uint32_t flags;
  const char* default_value; /* canonical string; NULL when LF_PARAM_REQUIRED */
  const char* doc;           /* one line */
  int32_t has_min, has_max;  /* numeric bounds (inclusive), per element for lists */
  double min_value, max_value;
  const char* choices;       /* LF_PARAM_ENUM: choices joined by '|' */
  /* Appended (read only when struct_size covers it): */
  const char* component_interface; /* LF_PARAM_COMPONENT: interface the chosen stage must
                                       implement, e.g. LF_REGISTRATION_INTERFACE; NULL: any */
} LfParamSpec;

/* A parameter value handed to a plugin. */
typedef struct LfParam {
  const char* name;
  const char* value;         /* canonical string */
} LfParam;

/* ---- Ports and artifacts ---------------------------------------------- */

enum {
  LF_PORT_OPTIONAL = 1u << 0,  /* may be left unwired */
  LF_PORT_MULTIPLE = 1u << 1   /* accepts a list of wires */
};

/* A typed input or output of a stage. Artifact types are dotted names such
 * as "kapture.dataset", "kapture.keypoints", "colmap.model", "report". */
typedef struct LfPortSpec {
  uint32_t struct_size;
  const char* name;
  const char* artifact_type;
  uint32_t flags;
  const char* doc;
} LfPortSpec;

/* A concrete input handed to a run: the folder holding the artifact. */
typedef struct LfArtifact {
  const char* port;
  const char* artifact_type;
  const char* path;           /* absolute folder of the artifact */
} LfArtifact;

/* ---- Run context (host -> plugin) -------------------------------------- */

/* Declared here because the run context's component callbacks name it: in C
 * a struct first named inside a parameter list would be a different type. */
struct LfStageInfo;

enum { LF_LOG_DEBUG = 0, LF_LOG_INFO = 1, LF_LOG_WARNING = 2 };

typedef struct LfRunContext {
  uint32_t struct_size;
  const char* workspace;      /* workspace root */
  const char* output_dir;     /* folder this node writes into (exists, empty at first) */
  const LfArtifact* inputs;
  uint32_t num_inputs;
  int32_t threads;            /* threads the stage may use */
  int32_t shard_index;        /* this process handles items with shard == shard_index */
  int32_t shard_count;        /* 1 when not sharded */
  void* host;                 /* opaque, passed back to the callbacks */
  void (*log)(void* host, int32_t level, const char* message);
  /* Progress of a whole-stage run (per-item stages get it from the host). */
  void (*progress)(void* host, uint64_t done, uint64_t total, const char* what);
  int32_t (*cancelled)(void* host);
  /* Creates a component (another stage used in-process, e.g. a registration
   * back-end) by "kind/name" with its parameters. Returns an instance handle
   * and its stage info, or NULL with `err` filled. */
  void* (*create_component)(void* host, const char* stage_id, const LfParam* params,
                            uint32_t num_params, const struct LfStageInfo** info,
                            LfError* err);
  void (*destroy_component)(void* host, const struct LfStageInfo* info, void* instance);
} LfRunContext;

/* ---- Stages ------------------------------------------------------------ */

enum {
  LF_STAGE_RUNNABLE = 1u << 0,  /* can be a graph node (has run or per-item calls) */
  LF_STAGE_PER_ITEM = 1u << 1,  /* uses list_items/process_item/finalize */
  LF_STAGE_SERIAL_ITEMS = 1u << 2, /* process_item is not thread-safe */
  LF_STAGE_NONDETERMINISTIC = 1u << 3 /* output varies between runs */
};

typedef void (*LfEmitItem)(void* user, const char* item);

typedef struct LfStageInfo {
  uint32_t struct_size;
  const char* kind;           /* e.g. "features", "registration", "source" */
  const char* name;           /* e.g. "sift"; the stage id is "kind/name" */
  const char* doc;            /* one line */
  const LfParamSpec* params;
  uint32_t num_params;
  const LfPortSpec* inputs;
  uint32_t num_inputs;
  const LfPortSpec* outputs;
  uint32_t num_outputs;
  uint32_t flags;
  /* Validates parameters without creating anything (the stage's Check()). */
  int32_t (*check_params)(const LfParam* params, uint32_t num_params, LfError* err);
  void* (*create)(const LfParam* params, uint32_t num_params, LfError* err);
  void (*destroy)(void* instance);
  /* Whole-stage run: reads ctx->inputs, writes under ctx->output_dir. */
  int32_t (*run)(void* instance, const LfRunContext* ctx, LfError* err);
  /* Per-item stages: the host lists items, runs process_item on its shard of
   * them in parallel (unless LF_STAGE_SERIAL_ITEMS), then finalize once all
   * items of all shards are done. Each item's output must be written
   * atomically so a killed run can resume. */
  int32_t (*list_items)(void* instance, const LfRunContext* ctx, LfEmitItem emit, void* user,
                        LfError* err);
  int32_t (*process_item)(void* instance, const LfRunContext* ctx, const char* item,
                          LfError* err);
  int32_t (*finalize)(void* instance, const LfRunContext* ctx, LfError* err);
  /* In-process component interface, e.g. "locforge.registration/1"; NULL if none.
   * `component` returns a pointer to the interface's function table. */
  const char* component_interface;
  const void* (*component)(void* instance);
  /* Appended (read only when struct_size covers it): */
  const char* version;        /* the stage's own version; NULL: its plugin's. Enters the
                                 cache key of the stage's results instead of the plugin's */
} LfStageInfo;

/* ---- Plugin ------------------------------------------------------------ */

typedef struct LfPluginInfo {
  uint32_t abi_version;       /* must equal the host's LF_ABI_VERSION */
  uint32_t struct_size;       /* sizeof(LfPluginInfo) the plugin was built with */
  const char* name;
  const char* version;        /* the plugin's own version; part of the cache keys of the
                                 results of its stages that declare no version of their own */
  const char* description;
  const char* sdk_version;    /* locforge SDK version it was built against */
  const LfStageInfo* stages;
  uint32_t num_stages;
} LfPluginInfo;

/* The one exported entry point. The host passes its ABI version; a plugin
 * that cannot serve it may return NULL. Must not throw. */
typedef const LfPluginInfo* (*LfPluginEntryFn)(uint32_t host_abi_version);

/* ---- Component interfaces ---------------------------------------------- */

/* A point cloud handed across the boundary without copying. Strides are in
 * bytes; optional arrays are NULL when absent. */
typedef struct LfPointCloudView {
  uint32_t struct_size;
  uint64_t num_points;
  const float* xyz;           /* required */
  uint32_t xyz_stride;
  const float* normals;       /* optional */
  uint32_t normals_stride;
  const double* times;        /* optional, seconds, per point */
  uint32_t times_stride;
} LfPointCloudView;

/* Result of one registration: a struct, not a bool (small_gicp style). */
typedef struct LfRegistrationResult {
  uint32_t struct_size;
  int32_t converged;
  int32_t iterations;
  uint64_t num_inliers;
  double inlier_fraction;     /* inliers / source points (overlap) */
  double final_error;         /* mean robust residual of inliers */
  double T_target_source[16]; /* row-major 4x4 */
  double information[36];     /* row-major 6x6, tangent order (rx, ry, rz, tx, ty, tz) */
} LfRegistrationResult;

#define LF_REGISTRATION_INTERFACE "locforge.registration/1"
typedef struct LfRegistrationInterface {
  uint32_t struct_size;
  /* Aligns `source` to `target` starting from `initial_T_target_source`
   * (row-major 4x4). Thread-safe across distinct instances. */
  int32_t (*align)(void* instance, const LfPointCloudView* source,
                   const LfPointCloudView* target, const double initial_T_target_source[16],
                   int32_t threads, LfRegistrationResult* result, LfError* err);
} LfRegistrationInterface;

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* LOCFORGE_ABI_H_ */
