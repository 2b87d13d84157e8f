// Command planetlod-flamenco-compile compiles a submitted job with Flamenco's
// own job compiler (the Manager's internal/manager/job_compilers package and
// its goja JavaScript engine) and prints the authored job as JSON, in the
// same shape as farm/flamenco/harness/compile.js:
//
//	planetlod-flamenco-compile JOB.json        the authored job
//	planetlod-flamenco-compile --job-type NAME the job type as the Manager lists it
//
// Like the Manager, it loads job types from a `scripts` folder next to its
// executable. JOB.json is a submitted job ({ "name", "type", "priority",
// "settings", "metadata" }); an optional "created" (local time,
// 2006-01-02T15:04:05) fixes the time the Manager would stamp on it.
// A job the compiler refuses prints the error and exits with status 1.
//
// build.py beside this file builds it inside a copy of Flamenco's module,
// since Go lets only Flamenco's own packages import its internal packages.
package main

import (
	"context"
	"encoding/json"
	"errors"
	"fmt"
	"os"
	"time"

	"github.com/rs/zerolog"

	"projects.blender.org/studio/flamenco/internal/manager/job_compilers"
	"projects.blender.org/studio/flamenco/pkg/api"
)

type fixedClock struct{ now time.Time }

func (c fixedClock) Now() time.Time { return c.now }

type outCommand struct {
	Name           string         `json:"name"`
	Parameters     map[string]any `json:"parameters"`
	TotalStepCount int            `json:"totalStepCount"`
}

type outTask struct {
	UUID         string       `json:"uuid"`
	Name         string       `json:"name"`
	Type         string       `json:"type"`
	Priority     int          `json:"priority"`
	Commands     []outCommand `json:"commands"`
	Dependencies []string     `json:"dependencies"`
}

type outJob struct {
	JobID    string            `json:"jobID"`
	Name     string            `json:"name"`
	JobType  string            `json:"jobType"`
	Priority int               `json:"priority"`
	Settings map[string]any    `json:"settings"`
	Metadata map[string]string `json:"metadata"`
	Tasks    []outTask         `json:"tasks"`
}

func compile(path string) (*outJob, error) {
	raw, err := os.ReadFile(path)
	if err != nil {
		return nil, err
	}
	var submitted api.SubmittedJob
	if err := json.Unmarshal(raw, &submitted); err != nil {
		return nil, fmt.Errorf("%s: %w", path, err)
	}
	var extra struct {
		Created  string `json:"created"`
		Priority *int   `json:"priority"`
	}
	if err := json.Unmarshal(raw, &extra); err != nil {
		return nil, fmt.Errorf("%s: %w", path, err)
	}
	created := time.Now()
	if extra.Created != "" {
		if created, err = time.ParseInLocation("2006-01-02T15:04:05", extra.Created, time.Local); err != nil {
			return nil, fmt.Errorf("%s: created: %w", path, err)
		}
	}
	if extra.Priority == nil {
		submitted.Priority = 50 // the Flamenco add-on's default
	}

	service, err := job_compilers.New(fixedClock{created})
	if err != nil {
		return nil, err
	}
	// The add-on submits the etag of the job type it showed; the Manager
	// refuses a job whose job type changed since.
	jobType, err := service.GetJobType(submitted.Type)
	if err != nil {
		return nil, err
	}
	submitted.TypeEtag = &jobType.Etag

	authored, err := service.Compile(context.Background(), submitted)
	if err != nil {
		return nil, err
	}
	out := &outJob{
		JobID:    authored.JobID,
		Name:     authored.Name,
		JobType:  authored.JobType,
		Priority: authored.Priority,
		Settings: authored.Settings,
		Metadata: authored.Metadata,
		Tasks:    []outTask{},
	}
	for _, task := range authored.Tasks {
		ot := outTask{UUID: task.UUID, Name: task.Name, Type: task.Type, Priority: task.Priority,
			Commands: []outCommand{}, Dependencies: []string{}}
		for _, command := range task.Commands {
			ot.Commands = append(ot.Commands, outCommand{command.Name, command.Parameters, command.TotalStepCount})
		}
		for _, dep := range task.Dependencies {
			ot.Dependencies = append(ot.Dependencies, dep.UUID)
		}
		out.Tasks = append(out.Tasks, ot)
	}
	return out, nil
}

func run(args []string) (any, error) {
	switch {
	case len(args) == 2 && args[0] == "--job-type":
		service, err := job_compilers.New(fixedClock{time.Now()})
		if err != nil {
			return nil, err
		}
		return service.GetJobType(args[1])
	case len(args) == 1:
		return compile(args[0])
	}
	return nil, errors.New("usage: planetlod-flamenco-compile SUBMITTED_JOB.json | --job-type NAME")
}

func main() {
	// The Manager's log lines go to stderr; stdout carries the JSON alone.
	zerolog.SetGlobalLevel(zerolog.WarnLevel)
	result, err := run(os.Args[1:])
	if err != nil {
		fmt.Fprintf(os.Stderr, "planetlod-flamenco-compile: %v\n", err)
		os.Exit(1)
	}
	encoded, err := json.MarshalIndent(result, "", " ")
	if err != nil {
		fmt.Fprintf(os.Stderr, "planetlod-flamenco-compile: %v\n", err)
		os.Exit(1)
	}
	os.Stdout.Write(append(encoded, '\n'))
}
